#include "sim_hal/scene/mesh_file_checks.hpp"

#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <sstream>
#include <vector>

namespace vantage::sim::detail {

namespace {

std::string read_all(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

bool is_number(const std::string& token) {
  if (token.empty()) return false;
  char* end = nullptr;
  errno = 0;
  std::strtod(token.c_str(), &end);
  return end == token.c_str() + token.size();
}

bool to_count(const std::string& token, std::uint64_t* out) {
  if (token.empty() || token.size() > 12) return false;
  std::uint64_t v = 0;
  for (char c : token) {
    if (c < '0' || c > '9') return false;
    v = v * 10 + static_cast<std::uint64_t>(c - '0');
  }
  *out = v;
  return true;
}

int ply_type_size(const std::string& t) {
  if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
  if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
  if (t == "int" || t == "uint" || t == "float" || t == "int32" || t == "uint32" || t == "float32") return 4;
  if (t == "double" || t == "float64") return 8;
  return 0;
}

struct PlyProperty {
  bool list = false;
  int count_size = 0;
  int item_size = 0;
};
struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::vector<PlyProperty> properties;
};

}  // namespace

std::string check_ply_structure(const std::string& path) {
  const std::string data = read_all(path);
  std::size_t pos = 0;
  auto next_line = [&](std::string* line) {
    if (pos >= data.size()) return false;
    std::size_t end = data.find('\n', pos);
    if (end == std::string::npos) end = data.size();
    *line = data.substr(pos, end - pos);
    if (!line->empty() && line->back() == '\r') line->pop_back();
    pos = end + 1;
    return true;
  };
  std::string line;
  if (!next_line(&line) || line != "ply") return "not a PLY file (first line is not 'ply')";
  std::string format;
  std::vector<PlyElement> elements;
  bool ended = false;
  while (next_line(&line)) {
    std::istringstream words(line);
    std::string keyword;
    words >> keyword;
    if (keyword.empty() || keyword == "comment" || keyword == "obj_info") continue;
    if (keyword == "end_header") {
      ended = true;
      break;
    }
    if (keyword == "format") {
      words >> format;
      if (format != "ascii" && format != "binary_little_endian" && format != "binary_big_endian") {
        return "unknown PLY format '" + format + "'";
      }
    } else if (keyword == "element") {
      PlyElement e;
      std::string count;
      words >> e.name >> count;
      if (!to_count(count, &e.count)) return "bad count in PLY header line '" + line + "'";
      elements.push_back(e);
    } else if (keyword == "property") {
      if (elements.empty()) return "PLY property before any element";
      std::string type;
      words >> type;
      PlyProperty p;
      if (type == "list") {
        std::string count_type, item_type;
        words >> count_type >> item_type;
        p.list = true;
        p.count_size = ply_type_size(count_type);
        p.item_size = ply_type_size(item_type);
        if (p.count_size == 0 || p.item_size == 0) return "bad PLY list property '" + line + "'";
      } else {
        p.item_size = ply_type_size(type);
        if (p.item_size == 0) return "bad PLY property type in '" + line + "'";
      }
      elements.back().properties.push_back(p);
    } else {
      return "unknown PLY header line '" + line + "'";
    }
  }
  if (!ended) return "PLY header has no end_header";
  if (format.empty()) return "PLY header has no format line";

  if (format == "ascii") {
    std::istringstream body(data.substr(pos));
    std::string token;
    for (const PlyElement& e : elements) {
      if (e.properties.empty()) continue;
      for (std::uint64_t i = 0; i < e.count; ++i) {
        for (const PlyProperty& p : e.properties) {
          std::uint64_t n = 1;
          if (p.list) {
            if (!(body >> token) || !to_count(token, &n)) return "truncated or malformed PLY data in element '" + e.name + "'";
          }
          for (std::uint64_t k = 0; k < n; ++k) {
            if (!(body >> token) || !is_number(token)) return "truncated or malformed PLY data in element '" + e.name + "'";
          }
        }
      }
    }
    return "";
  }
  const bool little = format == "binary_little_endian";
  std::uint64_t offset = pos;
  for (const PlyElement& e : elements) {
    if (e.properties.empty()) continue;
    for (std::uint64_t i = 0; i < e.count; ++i) {
      for (const PlyProperty& p : e.properties) {
        std::uint64_t n = 1;
        if (p.list) {
          if (offset + static_cast<std::uint64_t>(p.count_size) > data.size()) return "truncated PLY data in element '" + e.name + "'";
          n = 0;
          for (int b = 0; b < p.count_size; ++b) {
            const int byte = little ? p.count_size - 1 - b : b;
            n = (n << 8) | static_cast<unsigned char>(data[offset + static_cast<std::uint64_t>(byte)]);
          }
          offset += static_cast<std::uint64_t>(p.count_size);
        }
        offset += n * static_cast<std::uint64_t>(p.item_size);
        if (offset > data.size()) return "truncated PLY data in element '" + e.name + "'";
      }
    }
  }
  return "";
}

std::string check_off_structure(const std::string& path) {
  std::istringstream in(read_all(path));
  // Comments start with '#' and run to the end of the line.
  std::vector<std::string> tokens;
  std::string line;
  while (std::getline(in, line)) {
    const std::size_t hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    std::istringstream words(line);
    std::string w;
    while (words >> w) tokens.push_back(w);
  }
  std::size_t t = 0;
  if (tokens.empty() || tokens[0] != "OFF") return "not a plain OFF file (the first word is not 'OFF')";
  ++t;
  std::uint64_t nv = 0, nf = 0, ne = 0;
  if (tokens.size() < 4 || !to_count(tokens[1], &nv) || !to_count(tokens[2], &nf) || !to_count(tokens[3], &ne)) {
    return "bad OFF counts line";
  }
  t = 4;
  if (tokens.size() - t < nv * 3) return "truncated OFF vertex list";
  for (std::uint64_t i = 0; i < nv * 3; ++i, ++t) {
    if (!is_number(tokens[t])) return "malformed OFF vertex coordinate '" + tokens[t] + "'";
  }
  for (std::uint64_t f = 0; f < nf; ++f) {
    std::uint64_t n = 0;
    if (t >= tokens.size() || !to_count(tokens[t], &n)) return "truncated or malformed OFF face list";
    ++t;
    if (n < 3 || tokens.size() - t < n) return "truncated or malformed OFF face list";
    for (std::uint64_t k = 0; k < n; ++k, ++t) {
      std::uint64_t index = 0;
      if (!to_count(tokens[t], &index) || index >= nv) return "OFF face index out of range";
    }
    // Optional per-face colour values follow on the same line; they are numbers we skip over only when
    // they are not the next face's vertex count: plain OFF without colours is what we accept.
  }
  return "";
}

}  // namespace vantage::sim::detail
