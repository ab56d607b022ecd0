// The one Catch2 main of the OpenVDB tests (kept apart so that test files compile alone).
#define CATCH_CONFIG_MAIN
#include <catch2/catch.hpp>
