// Our own Catch2 v2 main: Debian's Catch2WithMain is x86-only, and this one builds for aarch64 too.
#define CATCH_CONFIG_RUNNER
#include <catch2/catch.hpp>

int main(int argc, char* argv[]) { return Catch::Session().run(argc, argv); }
