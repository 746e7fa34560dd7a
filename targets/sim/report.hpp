#pragma once
// The mission report written by --out DIR:
//   grid.png         Fig. 4-like: cost landscape (first and final evaluation), occupied cells, the two
//                    initial views, every NBV (numbered), the executed path
//   performance.png  Fig. 5-like: average sigma and utility U against the image count, replans marked
//   uncertainty.png  the primitives splatted into two views, coloured by sigma (red high, blue low)
//   model.ply        the primitives with per-vertex colour by sigma (and a sigma property)
//   summary.json     the mission's figures
//   *.dat, report.gp the plot data and the gnuplot script (re-run: cd DIR && gnuplot report.gp)
#include <string>

#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/model/primitive_pool.hpp"
#include "targets/sim/mission_trace.hpp"

namespace vantage::simtarget {

// Creates dir when missing and proves it writable with a probe file. false + a one-line error naming
// the folder otherwise. Call it before the mission starts.
bool prepare_output_dir(const std::string& dir, std::string* error);

// Writes every file of the report. false + error naming the file that failed; the other files are
// still attempted. gnuplot missing or failing is an error for the two plots only.
bool write_report(const std::string& dir, const MissionTrace& trace, const MissionSummary& summary,
                  const PrimitivePoolView& pool, const PinholeIntrinsics& intrinsics, double viewing_distance,
                  std::string* error);

std::string summary_json(const MissionSummary& summary);

}  // namespace vantage::simtarget
