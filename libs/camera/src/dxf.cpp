// ASCII DXF → LineModel. A DXF file is a sequence of (group code, value) line pairs; sections HEADER
// (variables "9 $NAME" followed by their value groups) and ENTITIES (each entity starts at a group 0 naming
// its type) are read, everything else is skipped. The text is walked pair by pair without building a token
// list, so memory stays at the file text plus the segments.

#include "evpipe/camera/error.hpp"
#include "line_model_detail.hpp"
#include "text_file.hpp"

#include <fmt/format.h>

#include <cmath>
#include <cstdint>
#include <map>
#include <optional>

namespace evpipe::camera::detail {
namespace {

struct Pair {
  int code{0};
  std::string_view value;
  std::size_t line{0};  ///< 1-based line of the group code; the value is on line + 1
};

class DxfCursor {
 public:
  DxfCursor(std::string_view text, const std::string& file) : text_(text), file_(file) {}

  /// The next pair, or nullopt at the end of the text.
  std::optional<Pair> next() {
    if (peeked_) {
      auto p = peeked_;
      peeked_.reset();
      return p;
    }
    return read_pair();
  }
  std::optional<Pair> peek() {
    if (!peeked_) peeked_ = read_pair();
    return peeked_;
  }
  /// Number of lines read so far (the last line of the file once the end is reached).
  [[nodiscard]] std::size_t lines_read() const { return line_; }

 private:
  bool next_line(std::string_view& out) {
    if (pos_ >= text_.size()) return false;
    const auto nl = text_.find('\n', pos_);
    const std::size_t end = nl == std::string_view::npos ? text_.size() : nl;
    out = text_.substr(pos_, end - pos_);
    if (!out.empty() && out.back() == '\r') out.remove_suffix(1);
    pos_ = nl == std::string_view::npos ? text_.size() : nl + 1;
    ++line_;
    return true;
  }

  std::optional<Pair> read_pair() {
    std::string_view code_line;
    // Blank lines between pairs are not valid DXF, but trailing ones at the end of a file are common.
    do {
      if (!next_line(code_line)) return std::nullopt;
    } while (trim(code_line).empty() && remaining_is_blank());
    Pair p;
    p.line = line_;
    const auto code = parse_int64(code_line);
    if (!code || *code < 0 || *code > 1071) {
      throw ModelError(file_, fmt::format("line {}", line_),
                       fmt::format("expected a DXF group code (integer 0..1071), got '{}'", excerpt(code_line)));
    }
    p.code = static_cast<int>(*code);
    std::string_view value;
    if (!next_line(value)) {
      throw ModelError(file_, fmt::format("line {}", line_), "DXF ends after a group code, without its value");
    }
    p.value = trim(value);
    return p;
  }

  bool remaining_is_blank() const { return trim(text_.substr(pos_)).empty(); }

  std::string_view text_;
  const std::string& file_;
  std::size_t pos_{0};
  std::size_t line_{0};
  std::optional<Pair> peeked_;
};

/// A raw segment in file units, with where it came from (for messages).
struct RawSegment {
  Eigen::Vector3d a;
  Eigen::Vector3d b;
  std::size_t line;    ///< line holding the entity's type name (the value line of its group 0)
  std::size_t entity;  ///< 1-based index among the ENTITIES section's entities
  const char* type;
};

/// DXF's "arbitrary axis algorithm": object coordinate system (OCS) of an extrusion direction N → world.
struct Ocs {
  Eigen::Vector3d ax{Eigen::Vector3d::UnitX()};
  Eigen::Vector3d ay{Eigen::Vector3d::UnitY()};
  Eigen::Vector3d az{Eigen::Vector3d::UnitZ()};
  bool identity{true};

  explicit Ocs(const Eigen::Vector3d& n) {
    if (n == Eigen::Vector3d::UnitZ()) return;  // the usual case: keep coordinates bit-exact
    identity = false;
    az = n.normalized();
    constexpr double kLimit = 1.0 / 64.0;
    ax = (std::abs(az.x()) < kLimit && std::abs(az.y()) < kLimit) ? Eigen::Vector3d::UnitY().cross(az)
                                                                  : Eigen::Vector3d::UnitZ().cross(az);
    ax.normalize();
    ay = az.cross(ax).normalized();
  }
  Eigen::Vector3d to_world(double x, double y, double z) const {
    if (identity) return {x, y, z};
    return x * ax + y * ay + z * az;
  }
};

class DxfParser {
 public:
  DxfParser(std::string_view text, const std::string& file) : cur_(text, file), file_(file) {}

  LineModel run(std::vector<std::string>* notes);

 private:
  [[noreturn]] void fail(std::size_t line, const std::string& what) const {
    throw ModelError(file_, fmt::format("line {}", line), what);
  }
  Pair require_next(const char* expecting) {
    auto p = cur_.next();
    if (!p) fail(cur_.lines_read(), fmt::format("DXF ends early: expected {}", expecting));
    return *p;
  }
  double number(const Pair& p) const {
    const auto v = parse_double(p.value);
    if (!v) fail(p.line + 1, fmt::format("group {}: not a finite number: '{}'", p.code, excerpt(p.value)));
    return *v;
  }
  std::int64_t integer(const Pair& p) const {
    const auto v = parse_int64(p.value);
    if (!v) fail(p.line + 1, fmt::format("group {}: not an integer: '{}'", p.code, excerpt(p.value)));
    return *v;
  }

  void skip_section();
  void read_header();
  void read_entities();
  /// The groups of the entity whose "0 / TYPE" pair was just read (up to, not including, the next group 0).
  std::vector<Pair> entity_groups();
  void read_line(const Pair& start, const std::vector<Pair>& groups);
  void read_lwpolyline(const Pair& start, const std::vector<Pair>& groups);
  void read_polyline(const Pair& start, const std::vector<Pair>& groups);
  void add_polyline(const std::vector<Eigen::Vector3d>& vertices, bool closed, const Pair& start);
  std::optional<double> find(const std::vector<Pair>& groups, int code) const {
    for (const auto& g : groups) {
      if (g.code == code) return number(g);
    }
    return std::nullopt;
  }
  Eigen::Vector3d extrusion(const std::vector<Pair>& groups) const {
    return {find(groups, 210).value_or(0.0), find(groups, 220).value_or(0.0), find(groups, 230).value_or(1.0)};
  }

  DxfCursor cur_;
  const std::string& file_;
  std::optional<std::int64_t> insunits_;
  std::size_t insunits_line_{0};
  std::vector<RawSegment> raw_;
  std::size_t entity_index_{0};
  std::map<std::string, std::size_t> ignored_;
  std::size_t skipped_duplicate_vertices_{0};
  std::size_t bulges_{0};
};

void DxfParser::skip_section() {
  while (true) {
    const Pair p = require_next("ENDSEC");
    if (p.code == 0 && p.value == "ENDSEC") return;
    if (p.code == 0 && p.value == "EOF") fail(p.line, "EOF inside a section (missing ENDSEC)");
  }
}

void DxfParser::read_header() {
  while (true) {
    const Pair p = require_next("ENDSEC");
    if (p.code == 0 && p.value == "ENDSEC") return;
    if (p.code == 0 && p.value == "EOF") fail(p.line, "EOF inside HEADER (missing ENDSEC)");
    if (p.code == 9 && p.value == "$INSUNITS") {
      const Pair v = require_next("the value of $INSUNITS");
      if (v.code != 70) fail(v.line, fmt::format("$INSUNITS: expected group 70, got group {}", v.code));
      insunits_ = integer(v);
      insunits_line_ = v.line + 1;
    }
  }
}

std::vector<Pair> DxfParser::entity_groups() {
  std::vector<Pair> groups;
  while (true) {
    const auto p = cur_.peek();
    if (!p || p->code == 0) return groups;
    groups.push_back(*cur_.next());
  }
}

void DxfParser::read_entities() {
  while (true) {
    const Pair start = require_next("ENDSEC");
    if (start.code != 0) fail(start.line, fmt::format("expected an entity (group 0), got group {}", start.code));
    if (start.value == "ENDSEC") return;
    if (start.value == "EOF") fail(start.line, "EOF inside ENTITIES (missing ENDSEC)");
    ++entity_index_;
    const std::vector<Pair> groups = entity_groups();
    if (start.value == "LINE") {
      read_line(start, groups);
    } else if (start.value == "LWPOLYLINE") {
      read_lwpolyline(start, groups);
    } else if (start.value == "POLYLINE") {
      read_polyline(start, groups);
    } else if (start.value == "VERTEX" || start.value == "SEQEND") {
      fail(start.line + 1, fmt::format("{} outside a POLYLINE", start.value));
    } else {
      ++ignored_[std::string(start.value)];
    }
  }
}

void DxfParser::read_line(const Pair& start, const std::vector<Pair>& groups) {
  static constexpr struct {
    int code;
    const char* what;
  } kCoords[6] = {{10, "start point x"}, {20, "start point y"}, {30, "start point z"},
                  {11, "end point x"},   {21, "end point y"},   {31, "end point z"}};
  double v[6];
  for (int i = 0; i < 6; ++i) {
    const auto found = find(groups, kCoords[i].code);
    if (!found) {
      fail(start.line + 1,
           fmt::format("LINE entity #{} has no {} (group {})", entity_index_, kCoords[i].what, kCoords[i].code));
    }
    v[i] = *found;
  }
  raw_.push_back({{v[0], v[1], v[2]}, {v[3], v[4], v[5]}, start.line + 1, entity_index_, "LINE"});
}

void DxfParser::add_polyline(const std::vector<Eigen::Vector3d>& vertices, bool closed, const Pair& start) {
  const char* type = start.value == "LWPOLYLINE" ? "LWPOLYLINE" : "POLYLINE";
  if (vertices.size() < 2) {
    ++ignored_[std::string(type) + " with fewer than 2 vertices"];
    return;
  }
  const std::size_t n = vertices.size();
  const std::size_t edges = closed ? n : n - 1;
  for (std::size_t i = 0; i < edges; ++i) {
    const Eigen::Vector3d& a = vertices[i];
    const Eigen::Vector3d& b = vertices[(i + 1) % n];
    if (a == b) {  // repeated vertex (e.g. a closed polyline that also repeats its first vertex)
      ++skipped_duplicate_vertices_;
      continue;
    }
    raw_.push_back({a, b, start.line + 1, entity_index_, type});
  }
}

void DxfParser::read_lwpolyline(const Pair& start, const std::vector<Pair>& groups) {
  struct Vertex {
    double x;
    std::optional<double> y;
    std::size_t line;
  };
  std::vector<Vertex> vs;
  double elevation = 0.0;
  std::int64_t flags = 0;
  for (const auto& g : groups) {
    switch (g.code) {
      case 10:
        vs.push_back({number(g), std::nullopt, g.line});
        break;
      case 20:
        if (vs.empty() || vs.back().y)
          fail(g.line, fmt::format("LWPOLYLINE entity #{}: group 20 without a preceding 10", entity_index_));
        vs.back().y = number(g);
        break;
      case 38:
        elevation = number(g);
        break;
      case 70:
        flags = integer(g);
        break;
      case 42:
        if (number(g) != 0.0) ++bulges_;
        break;
      default:
        break;
    }
  }
  const Ocs ocs(extrusion(groups));
  std::vector<Eigen::Vector3d> world;
  world.reserve(vs.size());
  for (const auto& v : vs) {
    if (!v.y) fail(v.line, fmt::format("LWPOLYLINE entity #{}: vertex without y (group 20)", entity_index_));
    world.push_back(ocs.to_world(v.x, *v.y, elevation));
  }
  add_polyline(world, (flags & 1) != 0, start);
}

void DxfParser::read_polyline(const Pair& start, const std::vector<Pair>& groups) {
  std::int64_t flags = 0;
  for (const auto& g : groups) {
    if (g.code == 70) flags = integer(g);
  }
  const bool is_3d = (flags & 8) != 0;
  const bool is_mesh = (flags & (16 | 64)) != 0;
  const double elevation = find(groups, 30).value_or(0.0);
  const Ocs ocs(extrusion(groups));
  std::vector<Eigen::Vector3d> vertices;
  while (true) {
    const Pair p = require_next("VERTEX or SEQEND");
    if (p.code != 0) fail(p.line, fmt::format("expected an entity (group 0), got group {}", p.code));
    if (p.value == "SEQEND") {
      entity_groups();  // SEQEND's own groups (handle, layer)
      break;
    }
    if (p.value != "VERTEX") {
      fail(p.line + 1, fmt::format("POLYLINE entity #{} (line {}): expected VERTEX or SEQEND, got {}", entity_index_,
                                   start.line + 1, p.value));
    }
    const std::vector<Pair> vg = entity_groups();
    std::int64_t vflags = 0;
    for (const auto& g : vg) {
      if (g.code == 70) vflags = integer(g);
    }
    if ((vflags & 16) != 0) continue;  // spline frame control point: not on the curve
    const auto x = find(vg, 10);
    const auto y = find(vg, 20);
    if (!x || !y)
      fail(p.line + 1,
           fmt::format("VERTEX of POLYLINE entity #{} has no {}", entity_index_, !x ? "x (group 10)" : "y (group 20)"));
    if (is_3d) {
      const auto z = find(vg, 30);
      if (!z) fail(p.line + 1, fmt::format("VERTEX of 3D POLYLINE entity #{} has no z (group 30)", entity_index_));
      vertices.emplace_back(*x, *y, *z);
    } else {
      if (find(vg, 42).value_or(0.0) != 0.0) ++bulges_;
      vertices.push_back(ocs.to_world(*x, *y, elevation));
    }
  }
  if (is_mesh) {
    ++ignored_["POLYLINE mesh (polyface/polygon)"];
    return;
  }
  add_polyline(vertices, (flags & 1) != 0, start);
}

LineModel DxfParser::run(std::vector<std::string>* notes) {
  bool saw_eof = false;
  bool saw_entities = false;
  while (auto p = cur_.next()) {
    if (p->code == 999) continue;  // comment
    if (p->code == 0 && p->value == "EOF") {
      saw_eof = true;
      break;
    }
    if (p->code != 0 || p->value != "SECTION") {
      fail(p->line, fmt::format("expected '0 / SECTION' or '0 / EOF', got group {} '{}'", p->code, excerpt(p->value)));
    }
    const Pair name = require_next("the section name (group 2)");
    if (name.code != 2) fail(name.line, fmt::format("expected the section name (group 2), got group {}", name.code));
    if (name.value == "HEADER") {
      read_header();
    } else if (name.value == "ENTITIES") {
      saw_entities = true;
      read_entities();
    } else {
      skip_section();
    }
  }
  if (!saw_eof) throw ModelError(file_, "", "DXF has no '0 / EOF' at the end (truncated?)");
  if (!saw_entities) throw ModelError(file_, "", "DXF has no ENTITIES section");

  double per_m = 1000.0;
  std::vector<std::string> remarks;
  if (!insunits_) {
    remarks.push_back("DXF: no $INSUNITS in the HEADER: coordinates taken as millimetres");
  } else if (*insunits_ == 0) {
    remarks.push_back("DXF: $INSUNITS = 0 (unitless): coordinates taken as millimetres");
  } else if (*insunits_ == 4) {
    per_m = 1000.0;
  } else if (*insunits_ == 6) {
    per_m = 1.0;
  } else {
    throw ModelError(
        file_, fmt::format("line {}", insunits_line_),
        fmt::format("unknown units: $INSUNITS = {} (supported: 4 = mm, 6 = m, 0 or absent = mm)", *insunits_));
  }

  LineModel out;
  out.name = stem_of(file_);
  out.segments_m.reserve(raw_.size());
  for (const auto& r : raw_) {
    Segment3 s{to_metres(r.a.x(), r.a.y(), r.a.z(), per_m), to_metres(r.b.x(), r.b.y(), r.b.z(), per_m)};
    if (!(s.length_m() >= kMinSegmentLength_m)) {
      fail(r.line, fmt::format("{} entity #{}: zero-length segment", r.type, r.entity));
    }
    out.segments_m.push_back(s);
  }
  if (out.segments_m.empty()) {
    throw ModelError(file_, "", "DXF has no line segments (LINE, POLYLINE or LWPOLYLINE) in ENTITIES");
  }

  for (const auto& [type, count] : ignored_) {
    remarks.push_back(fmt::format("DXF: ignored {} {} entit{} (only LINE, POLYLINE and LWPOLYLINE are read{})", count,
                                  type, count == 1 ? "y" : "ies",
                                  type == "INSERT" ? "; block references are not expanded" : ""));
  }
  if (skipped_duplicate_vertices_ > 0) {
    remarks.push_back(fmt::format("DXF: skipped {} zero-length polyline edge(s) from repeated vertices",
                                  skipped_duplicate_vertices_));
  }
  if (bulges_ > 0) {
    remarks.push_back(fmt::format("DXF: {} polyline arc(s) (bulge) replaced by their chord", bulges_));
  }
  if (notes != nullptr) notes->insert(notes->end(), remarks.begin(), remarks.end());
  return out;
}

}  // namespace

bool looks_like_dxf(std::string_view text) {
  text = strip_bom(text);
  std::size_t pos = 0;
  while (pos < text.size()) {
    const auto nl = text.find('\n', pos);
    const std::string_view line = trim(text.substr(pos, nl == std::string_view::npos ? text.size() - pos : nl - pos));
    if (!line.empty()) return line == "0" || line == "999";
    if (nl == std::string_view::npos) break;
    pos = nl + 1;
  }
  return false;
}

LineModel parse_line_model_dxf(std::string_view text, const std::string& file, std::vector<std::string>* notes) {
  return DxfParser(strip_bom(text), file).run(notes);
}

}  // namespace evpipe::camera::detail
