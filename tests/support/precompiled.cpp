// The owner of the suites' precompiled headers (tests/CMakeLists.txt, VSURG_TEST_PCH): every
// suite reuses the headers compiled here instead of parsing GoogleTest, Eigen, JSON and the
// standard library's containers again. Nothing else is in this file.
