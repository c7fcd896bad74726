// The precompiled header's own target (test/CMakeLists.txt): the test executables reuse it.
