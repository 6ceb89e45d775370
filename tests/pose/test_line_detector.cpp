// placeholder: written with the pose issue (issue 5)
