// placeholder: implemented by the pose issue (issue 5)
