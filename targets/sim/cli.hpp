#pragma once
// vantage-sim's command line (CLI11) and the run it describes: one mission or the comparison of every
// planner, each with its report. Exit codes: 0 goals reached (every run with --compare), 1 bad input or
// simulator error, 2 budget exhausted before the goals, 3 a planner failed.
#include <string>
#include <vector>

namespace vantage::simtarget {

// argv-style entry point used by main() and by the end-to-end tests.
int run_cli(int argc, const char* const* argv);

}  // namespace vantage::simtarget
