#pragma once
// What every camera guest program shares: the PASS/FAIL console protocol that guest-init.sh reads, and
// the frame checks (hash against the goldens, variety of gray values).
#include <cinttypes>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include "core/image/gray_image.hpp"

namespace vantage::vm_guest {

// FAIL lines printed so far; the program's exit code is non-zero when any.
inline int g_failures = 0;

inline void pass(const std::string& name, const std::string& detail) {
  std::printf("PASS %s: %s\n", name.c_str(), detail.c_str());
}
inline void fail(const std::string& name, const std::string& detail) {
  std::printf("FAIL %s: %s\n", name.c_str(), detail.c_str());
  ++g_failures;
}

// FNV-1a 64 over the image's rows (not the stride padding): the golden hashes in tests/vm/goldens.
inline std::uint64_t hash_gray(const MutableGrayImageView& image) {
  std::uint64_t h = 14695981039346656037ull;
  for (std::int32_t y = 0; y < image.height_px; ++y) {
    const std::uint8_t* row = image.pixels + static_cast<std::ptrdiff_t>(y) * image.stride_bytes;
    for (std::int32_t x = 0; x < image.width_px; ++x) {
      h ^= row[x];
      h *= 1099511628211ull;
    }
  }
  return h;
}

// How many of the 256 gray values occur: a test pattern has many, a black or stuck frame few.
inline int distinct_values(const MutableGrayImageView& image) {
  bool seen[256] = {};
  int count = 0;
  for (std::int32_t y = 0; y < image.height_px; ++y) {
    for (std::int32_t x = 0; x < image.width_px; ++x) {
      const std::uint8_t v = image.at(x, y);
      if (!seen[v]) {
        seen[v] = true;
        ++count;
      }
    }
  }
  return count;
}

// The golden hashes: one "device format size hash" line each, '#' comments. Empty, with the reason in
// *error (file and line), when the file cannot be read or a line is malformed.
inline std::map<std::string, std::string> read_goldens(const char* path, std::string* error) {
  std::map<std::string, std::string> goldens;
  std::ifstream in(path);
  if (!in) {
    *error = std::string(path) + ": cannot be read";
    return {};
  }
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    std::string device, format, size, hash, extra;
    if (!(fields >> device >> format >> size >> hash) || (fields >> extra)) {
      *error = std::string(path) + ":" + std::to_string(number) + ": expected 'device format size hash'";
      return {};
    }
    goldens[device + " " + format + " " + size] = hash;
  }
  if (goldens.empty()) *error = std::string(path) + ": no golden hashes";
  return goldens;
}

inline std::string hex(std::uint64_t value) {
  char text[17];
  std::snprintf(text, sizeof text, "%016" PRIx64, value);
  return text;
}

}  // namespace vantage::vm_guest
