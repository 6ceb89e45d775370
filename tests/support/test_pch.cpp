// The anchor of the tests' shared precompiled header (tests/CMakeLists.txt, evpipe_test_pch): CMake builds the header
// with this object's flags, and every test executable reuses it. Nothing else belongs here.
