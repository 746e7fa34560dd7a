// vantage-sim: the paper's experiment (section VI) in the simulator. See targets/sim/README.md.
#include "targets/sim/cli.hpp"

int main(int argc, char** argv) { return vantage::simtarget::run_cli(argc, argv); }
