#pragma once
// Structural checks of PLY and OFF files before assimp sees them: assimp 5.2 hangs on a PLY header
// without end_header and crashes (abort, segfault) on truncated OFF and binary PLY data. The checks walk
// the file's structure (counts, list lengths, indices, byte sizes) without building a mesh.
#include <string>

namespace vantage::sim::detail {

// Empty string when the file is well formed, else the problem (one line, no file name).
std::string check_ply_structure(const std::string& path);
std::string check_off_structure(const std::string& path);

}  // namespace vantage::sim::detail
