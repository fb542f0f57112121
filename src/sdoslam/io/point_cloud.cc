#include "sdoslam/io/point_cloud.h"

#include <fmt/format.h>

#include <bit>
#include <cstring>
#include <fstream>
#include <sstream>

#include "sdoslam/core/error.h"
#include "sdoslam/core/regular_file.h"

namespace sdoslam {

static_assert(std::endian::native == std::endian::little,
              "PLY binary_little_endian is written and read as the machine's own byte order");

void WritePly(std::ostream& out, const std::vector<ColoredPoint>& points,
              const std::vector<std::string>& comments) {
  out << "ply\nformat binary_little_endian 1.0\n";
  for (const std::string& comment : comments) out << "comment " << comment << "\n";
  out << "element vertex " << points.size() << "\n"
      << "property float x\nproperty float y\nproperty float z\n"
      << "property uchar red\nproperty uchar green\nproperty uchar blue\n"
      << "end_header\n";
  for (const ColoredPoint& p : points) {
    char record[15];
    std::memcpy(record, p.position.data(), 12);
    std::memcpy(record + 12, p.rgb.data(), 3);
    out.write(record, sizeof(record));
  }
}

namespace {

struct Property {
  std::string name;
  int size = 0;  // bytes
  bool is_float = false, is_signed = false;
};

// PLY's scalar type names (both spellings) and their sizes.
bool ParseScalarType(const std::string& type, Property* p) {
  struct Type {
    const char *name, *alias;
    int size;
    bool is_float, is_signed;
  };
  static constexpr Type kTypes[] = {
      {"char", "int8", 1, false, true},    {"uchar", "uint8", 1, false, false},
      {"short", "int16", 2, false, true},  {"ushort", "uint16", 2, false, false},
      {"int", "int32", 4, false, true},    {"uint", "uint32", 4, false, false},
      {"float", "float32", 4, true, true}, {"double", "float64", 8, true, true}};
  for (const Type& t : kTypes) {
    if (type == t.name || type == t.alias) {
      p->size = t.size;
      p->is_float = t.is_float;
      p->is_signed = t.is_signed;
      return true;
    }
  }
  return false;
}

double ReadBinaryScalar(const char* bytes, const Property& p) {
  if (p.is_float) {
    if (p.size == 4) {
      float f;
      std::memcpy(&f, bytes, 4);
      return f;
    }
    double d;
    std::memcpy(&d, bytes, 8);
    return d;
  }
  uint64_t u = 0;
  std::memcpy(&u, bytes, static_cast<size_t>(p.size));
  if (p.is_signed && p.size < 8 && (u >> (8 * p.size - 1)) != 0) {
    return static_cast<double>(static_cast<int64_t>(u | (~uint64_t{0} << (8 * p.size))));
  }
  return static_cast<double>(u);
}

// A PLY header as ReadPly reads it: the vertex element's size and properties.
struct PlyHeader {
  bool binary = false;
  size_t vertex_count = 0;
  std::vector<Property> properties;
};

// Reads the header of `in` up to end_header; `line_number` counts its lines. Throws Error
// naming `path` and the line.
PlyHeader ReadPlyHeader(std::istream& in, const std::filesystem::path& path, int* line_number) {
  const auto fail = [&](int line, const std::string& what) -> Error {
    return Error(fmt::format("{}:{}: {}", path.string(), line, what));
  };
  PlyHeader header;
  std::string line;
  bool in_vertex = false, seen_vertex = false;
  while (true) {
    if (!std::getline(in, line)) throw fail((*line_number), "the header has no end_header");
    ++*line_number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream words(line);
    std::string keyword;
    words >> keyword;
    if ((*line_number) == 1) {
      if (keyword != "ply") throw fail(1, "not a PLY file (it does not start with \"ply\")");
      continue;
    }
    if (keyword == "end_header") break;
    if (keyword == "comment" || keyword == "obj_info" || keyword.empty()) continue;
    if (keyword == "format") {
      std::string format;
      words >> format;
      if (format == "binary_little_endian") {
        header.binary = true;
      } else if (format != "ascii") {
        throw fail((*line_number),
                   "format " + format + " is not read (ascii, binary_little_endian)");
      }
    } else if (keyword == "element") {
      std::string name;
      long long count = -1;
      words >> name >> count;
      if (!words || count < 0) throw fail((*line_number), "malformed element line");
      in_vertex = name == "vertex";
      if (in_vertex) {
        if (seen_vertex) throw fail((*line_number), "a second vertex element");
        seen_vertex = true;
        header.vertex_count = static_cast<size_t>(count);
      } else if (!seen_vertex) {
        throw fail((*line_number), "element " + name + " before the vertices is not read");
      }
    } else if (keyword == "property") {
      if (!in_vertex) continue;  // properties of elements after the vertices: ignored
      std::string type, name;
      words >> type >> name;
      Property p;
      p.name = name;
      if (type == "list") throw fail((*line_number), "a list property in the vertex element");
      if (!ParseScalarType(type, &p)) throw fail((*line_number), "unknown property type " + type);
      header.properties.push_back(p);
    } else {
      throw fail((*line_number), "unknown header line \"" + line + "\"");
    }
  }
  if (!seen_vertex) throw fail(*line_number, "no vertex element");
  return header;
}

}  // namespace

std::vector<ColoredPoint> ReadPly(const std::filesystem::path& path) {
  RejectNonRegularFile(path);  // before the open: a FIFO would block it
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path.string() + ": cannot open");
  const auto fail = [&](int line, const std::string& what) -> Error {
    return Error(fmt::format("{}:{}: {}", path.string(), line, what));
  };
  int line_number = 0;
  const PlyHeader header = ReadPlyHeader(in, path, &line_number);
  const bool binary = header.binary;
  const size_t vertex_count = header.vertex_count;
  const std::vector<Property>& properties = header.properties;
  std::string line;
  const char* kWanted[] = {"x", "y", "z", "red", "green", "blue"};
  int index_of[6];
  for (int k = 0; k < 6; ++k) {
    index_of[k] = -1;
    for (size_t j = 0; j < properties.size(); ++j) {
      if (properties[j].name == kWanted[k]) index_of[k] = static_cast<int>(j);
    }
    if (index_of[k] < 0) {
      throw fail(line_number, fmt::format("the vertex element has no property {}", kWanted[k]));
    }
  }
  size_t record_size = 0;
  std::vector<size_t> offset;
  for (const Property& p : properties) {
    offset.push_back(record_size);
    record_size += static_cast<size_t>(p.size);
  }
  std::vector<ColoredPoint> points(vertex_count);
  std::vector<double> values(properties.size());
  std::string record(record_size, '\0');
  for (size_t i = 0; i < vertex_count; ++i) {
    if (binary) {
      if (!in.read(record.data(), static_cast<std::streamsize>(record_size))) {
        throw Error(fmt::format("{}: truncated: vertex {} of {} is missing", path.string(), i,
                                vertex_count));
      }
      for (size_t j = 0; j < properties.size(); ++j) {
        values[j] = ReadBinaryScalar(record.data() + offset[j], properties[j]);
      }
    } else {
      if (!std::getline(in, line)) {
        throw Error(fmt::format("{}: truncated: vertex {} of {} is missing", path.string(), i,
                                vertex_count));
      }
      ++line_number;
      std::istringstream words(line);
      for (double& v : values) {
        if (!(words >> v)) throw fail(line_number, "too few or malformed vertex values");
      }
    }
    ColoredPoint& p = points[i];
    for (int k = 0; k < 3; ++k) p.position[k] = static_cast<float>(values[index_of[k]]);
    for (int k = 0; k < 3; ++k) {
      const double c = values[index_of[3 + k]];
      if (c < 0 || c > 255) {
        throw Error(fmt::format("{}: vertex {}: colour {} outside 0-255", path.string(), i, c));
      }
      p.rgb[k] = static_cast<uint8_t>(c);
    }
  }
  return points;
}

}  // namespace sdoslam
