// The translation unit that builds the precompiled header every test executable reuses (see
// sdoslam_test_pch in CMakeLists.txt). It holds no code of its own.
