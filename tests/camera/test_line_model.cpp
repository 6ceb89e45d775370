// Line models: the shipped files, YAML vs DXF equality, DXF polylines/units/OCS, loader errors, the planar
// target's lack of symmetry, and project_segment().

#include "camera_test_util.hpp"
#include "evpipe/camera/line_model.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>

namespace evpipe::camera {
namespace {

using test::config_file;
using test::model_error_message;
using ::testing::HasSubstr;

Eigen::Vector3d mm(double x, double y, double z) {
  return Eigen::Vector3d(x, y, z) / 1000.0;
}

TEST(LineModelShipped, PlanarTarget) {
  const LineModel m = load_line_model(config_file("target-planar.yaml"));
  EXPECT_EQ(m.name, "target-planar");
  ASSERT_EQ(m.segments_m.size(), 9u);
  // mm → m: the first row is [-200, -150, 0, 200, -150, 0] mm.
  EXPECT_EQ(m.segments_m[0].a_m, Eigen::Vector3d(-0.2, -0.15, 0.0));
  EXPECT_EQ(m.segments_m[0].b_m, Eigen::Vector3d(0.2, -0.15, 0.0));
  for (const auto& s : m.segments_m) {
    EXPECT_EQ(s.a_m.z(), 0.0);
    EXPECT_EQ(s.b_m.z(), 0.0);
    EXPECT_LE(std::abs(s.a_m.x()), 0.2);
    EXPECT_LE(std::abs(s.a_m.y()), 0.15);
  }
}

TEST(LineModelShipped, RoadheaderYamlAndDxfAreIdentical) {
  std::vector<std::string> yaml_notes;
  std::vector<std::string> dxf_notes;
  const LineModel y = load_line_model(config_file("roadheader-wireframe.yaml"), &yaml_notes);
  const LineModel d = load_line_model(config_file("roadheader-wireframe.dxf"), &dxf_notes);
  EXPECT_TRUE(yaml_notes.empty());
  EXPECT_TRUE(dxf_notes.empty()) << dxf_notes.front();  // $INSUNITS 4 is present, only LINE entities
  EXPECT_EQ(y.name, "roadheader-wireframe");
  EXPECT_EQ(d.name, "roadheader-wireframe");
  ASSERT_EQ(y.segments_m.size(), 29u);
  ASSERT_EQ(d.segments_m.size(), 29u);
  for (std::size_t i = 0; i < y.segments_m.size(); ++i) EXPECT_EQ(y.segments_m[i], d.segments_m[i]) << "segment " << i;
  // The paper's model size: 900 x 393 x 308 mm.
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9);
  Eigen::Vector3d hi = -lo;
  for (const auto& s : y.segments_m) {
    lo = lo.cwiseMin(s.a_m).cwiseMin(s.b_m);
    hi = hi.cwiseMax(s.a_m).cwiseMax(s.b_m);
  }
  EXPECT_NEAR(hi.x() - lo.x(), 0.900, 1e-12);
  EXPECT_NEAR(hi.y() - lo.y(), 0.393, 1e-12);
  EXPECT_NEAR(hi.z() - lo.z(), 0.308, 1e-12);
  EXPECT_EQ(lo, Eigen::Vector3d(0.0, -0.1965, 0.0));  // origin on the floor at the rear edge's middle
}

TEST(LineModelYaml, MetresAndDefaultName) {
  std::vector<std::string> notes;
  const LineModel m =
      parse_line_model("model:\n  units: m\n  lines:\n    - [0, 0, 0, 0.3, 0, 0]\n", "dir/my-target.yaml", &notes);
  EXPECT_EQ(m.name, "my-target");
  ASSERT_EQ(m.segments_m.size(), 1u);
  EXPECT_EQ(m.segments_m[0].b_m, Eigen::Vector3d(0.3, 0.0, 0.0));
  EXPECT_TRUE(notes.empty());
}

TEST(LineModelYamlErrors, NameFileAndField) {
  const auto parse = [](const std::string& lines, const std::string& units = "mm") {
    return model_error_message(
        [&] { (void)parse_line_model("model:\n  name: t\n  units: " + units + "\n  lines:\n" + lines, "model.yaml"); });
  };
  const std::string ok = "    - [0, 0, 0, 300, 0, 0]\n";
  EXPECT_EQ(parse(ok + "    - [300, 0, 0, 300, 200]\n"),
            "model.yaml: model.lines[1]: expected 6 numbers (x1, y1, z1, x2, y2, z2), got 5");
  EXPECT_EQ(parse(ok + ok + ok + "    - [1, 2, 3, 1, 2, 3]\n"), "model.yaml: model.lines[3]: zero-length segment");
  EXPECT_EQ(parse(ok, "cm"), "model.yaml: model.units: unknown units 'cm' (expected mm or m)");
  EXPECT_EQ(parse(ok + "    - [0, 0, .nan, 1, 1, 1]\n"), "model.yaml: model.lines[1][2]: not a finite number: '.nan'");
  EXPECT_EQ(parse(ok + "    - [0, 0, x, 1, 1, 1]\n"), "model.yaml: model.lines[1][2]: not a finite number: 'x'");
  EXPECT_EQ(parse(ok + "    - 7\n"), "model.yaml: model.lines[1]: must be a list of numbers, e.g. [1, 2, 3]");
  EXPECT_EQ(model_error_message([] { (void)parse_line_model("model:\n  units: mm\n  lines: []\n", "model.yaml"); }),
            "model.yaml: model.lines: no segments (at least 1 is needed)");
  EXPECT_EQ(
      model_error_message([] { (void)parse_line_model("model:\n  lines: [[0, 0, 0, 1, 0, 0]]\n", "model.yaml"); }),
      "model.yaml: model.units: missing (mm or m)");
  EXPECT_THAT(model_error_message([] { (void)parse_line_model("model:\n  units: mm\n  line: []\n", "model.yaml"); }),
              HasSubstr("model.yaml: model.line: unknown key"));
  EXPECT_EQ(model_error_message([] { (void)parse_line_model("camera: {}\n", "model.yaml"); }),
            "model.yaml: model: missing");
  // Through the file loader: the message names the path.
  const std::string path =
      test::write_file("bad-model.yaml", "model:\n  units: mm\n  lines:\n    - [0, 0, 0, 0, 0, 0]\n");
  EXPECT_EQ(model_error_message([&] { (void)load_line_model(path); }), path + ": model.lines[0]: zero-length segment");
}

// ---- DXF ------------------------------------------------------------------------------------------------

/// Joins "code", "value" pairs into DXF text (codes right-aligned as AutoCAD writes them).
std::string dxf(std::initializer_list<std::pair<int, std::string>> pairs) {
  std::string out;
  for (const auto& [code, value] : pairs) {
    out += code < 10 ? "  " : code < 100 ? " " : "";
    out += std::to_string(code);
    out += '\n';
    out += value;
    out += '\n';
  }
  return out;
}

std::string header_mm() {
  return dxf({{0, "SECTION"}, {2, "HEADER"}, {9, "$INSUNITS"}, {70, "4"}, {0, "ENDSEC"}});
}
std::string entities() {
  return dxf({{0, "SECTION"}, {2, "ENTITIES"}});
}
std::string end_of_file() {
  return dxf({{0, "ENDSEC"}, {0, "EOF"}});
}

TEST(LineModelDxf, PolylinesAndLines) {
  const std::string text =
      header_mm() + entities() +
      // closed LWPOLYLINE rectangle at elevation 50: 4 edges
      dxf({{0, "LWPOLYLINE"},
           {8, "0"},
           {90, "4"},
           {70, "1"},
           {38, "50"},
           {10, "0"},
           {20, "0"},
           {10, "100"},
           {20, "0"},
           {10, "100"},
           {20, "60"},
           {10, "0"},
           {20, "60"}}) +
      // open 3D POLYLINE with 3 vertices: 2 edges
      dxf({{0, "POLYLINE"}, {8, "0"},  {66, "1"}, {10, "0"},  {20, "0"},     {30, "0"},     {70, "8"},
           {0, "VERTEX"},   {8, "0"},  {10, "1"}, {20, "2"},  {30, "3"},     {70, "32"},    {0, "VERTEX"},
           {8, "0"},        {10, "4"}, {20, "5"}, {30, "6"},  {70, "32"},    {0, "VERTEX"}, {8, "0"},
           {10, "7"},       {20, "8"}, {30, "9"}, {70, "32"}, {0, "SEQEND"}, {8, "0"}}) +
      dxf({{0, "LINE"}, {8, "0"}, {10, "1"}, {20, "1"}, {30, "1"}, {11, "2"}, {21, "2"}, {31, "2"}}) + end_of_file();
  std::vector<std::string> notes;
  const LineModel m = parse_line_model(text, "parts.dxf", &notes);
  EXPECT_TRUE(notes.empty());
  EXPECT_EQ(m.name, "parts");
  ASSERT_EQ(m.segments_m.size(), 7u);
  EXPECT_EQ(m.segments_m[0].a_m, mm(0, 0, 50));
  EXPECT_EQ(m.segments_m[0].b_m, mm(100, 0, 50));
  EXPECT_EQ(m.segments_m[3].a_m, mm(0, 60, 50));  // closing edge
  EXPECT_EQ(m.segments_m[3].b_m, mm(0, 0, 50));
  EXPECT_EQ(m.segments_m[4].a_m, mm(1, 2, 3));
  EXPECT_EQ(m.segments_m[5].b_m, mm(7, 8, 9));
  EXPECT_EQ(m.segments_m[6].a_m, mm(1, 1, 1));
}

TEST(LineModelDxf, ClosedPolylineWithRepeatedVertexAndOtherEntities) {
  const std::string text = header_mm() + entities() +
                           dxf({{0, "POLYLINE"}, {66, "1"}, {70, "9"},  // 3D + closed
                                {0, "VERTEX"},   {10, "0"}, {20, "0"},     {30, "0"},  {0, "VERTEX"}, {10, "10"},
                                {20, "0"},       {30, "0"}, {0, "VERTEX"}, {10, "10"}, {20, "10"},    {30, "0"},
                                {0, "VERTEX"},   {10, "0"}, {20, "0"},     {30, "0"},  {0, "SEQEND"}}) +
                           dxf({{0, "CIRCLE"}, {10, "0"}, {20, "0"}, {30, "0"}, {40, "5"}}) +
                           dxf({{0, "INSERT"}, {2, "BLOCK1"}}) + end_of_file();
  std::vector<std::string> notes;
  const LineModel m = parse_line_model(text, "tri.dxf", &notes);
  ASSERT_EQ(m.segments_m.size(), 3u);  // the closing edge from the repeated vertex to itself is skipped
  EXPECT_EQ(m.segments_m[2].a_m, mm(10, 10, 0));
  EXPECT_EQ(m.segments_m[2].b_m, mm(0, 0, 0));
  ASSERT_EQ(notes.size(), 3u);
  EXPECT_THAT(notes[0], HasSubstr("ignored 1 CIRCLE entity"));
  EXPECT_THAT(notes[1], HasSubstr("ignored 1 INSERT entity"));
  EXPECT_THAT(notes[1], HasSubstr("block references are not expanded"));
  EXPECT_THAT(notes[2], HasSubstr("skipped 1 zero-length polyline edge"));
}

TEST(LineModelDxf, UnitsDefaultsAndObjectCoordinates) {
  const std::string line = dxf({{0, "LINE"}, {10, "1"}, {20, "2"}, {30, "3"}, {11, "4"}, {21, "5"}, {31, "6"}});
  std::vector<std::string> notes;
  // No HEADER: millimetres, said in a note.
  const LineModel no_header = parse_line_model(entities() + line + end_of_file(), "a.dxf", &notes);
  EXPECT_EQ(no_header.segments_m[0].a_m, mm(1, 2, 3));
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_THAT(notes[0], HasSubstr("no $INSUNITS"));
  // $INSUNITS 6: metres.
  const std::string header_m =
      dxf({{0, "SECTION"}, {2, "HEADER"}, {9, "$ACADVER"}, {1, "AC1015"}, {9, "$INSUNITS"}, {70, "6"}, {0, "ENDSEC"}});
  const LineModel metres = parse_line_model(header_m + entities() + line + end_of_file(), "b.dxf");
  EXPECT_EQ(metres.segments_m[0].b_m, Eigen::Vector3d(4, 5, 6));
  // An LWPOLYLINE drawn with extrusion (0, 0, -1) (a mirrored view): OCS x = -world x, z = -elevation.
  const LineModel ocs = parse_line_model(header_mm() + entities() +
                                             dxf({{0, "LWPOLYLINE"},
                                                  {70, "0"},
                                                  {38, "7"},
                                                  {10, "10"},
                                                  {20, "20"},
                                                  {10, "30"},
                                                  {20, "20"},
                                                  {210, "0"},
                                                  {220, "0"},
                                                  {230, "-1"}}) +
                                             end_of_file(),
                                         "c.dxf");
  ASSERT_EQ(ocs.segments_m.size(), 1u);
  EXPECT_LT((ocs.segments_m[0].a_m - mm(-10, 20, -7)).norm(), 1e-15);
  EXPECT_LT((ocs.segments_m[0].b_m - mm(-30, 20, -7)).norm(), 1e-15);
  // CRLF line ends and a byte order mark are accepted.
  std::string crlf;
  for (char c : header_mm() + entities() + line + end_of_file())
    crlf += c == '\n' ? std::string("\r\n") : std::string(1, c);
  EXPECT_EQ(parse_line_model("\xEF\xBB\xBF" + crlf, "d.dxf").segments_m[0].a_m, mm(1, 2, 3));
}

/// 1-based line number of the n-th (1-based) line equal to `needle` in `text`.
std::size_t line_of(const std::string& text, const std::string& needle, int nth = 1) {
  std::size_t line = 0;
  std::size_t pos = 0;
  while (pos <= text.size()) {
    const auto nl = text.find('\n', pos);
    ++line;
    if (text.substr(pos, nl - pos) == needle && --nth == 0) return line;
    if (nl == std::string::npos) break;
    pos = nl + 1;
  }
  return 0;
}

TEST(LineModelDxfErrors, NameFileAndLine) {
  const std::string good = dxf({{0, "LINE"}, {10, "0"}, {20, "0"}, {30, "0"}, {11, "1"}, {21, "0"}, {31, "0"}});
  // LINE missing its end point y: the message names the line holding "LINE" of that entity.
  const std::string missing = header_mm() + entities() + good +
                              dxf({{0, "LINE"}, {10, "0"}, {20, "0"}, {30, "0"}, {11, "1"}, {31, "0"}}) + end_of_file();
  EXPECT_EQ(model_error_message([&] { (void)parse_line_model(missing, "model.dxf"); }),
            "model.dxf: line " + std::to_string(line_of(missing, "LINE", 2)) +
                ": LINE entity #2 has no end point y (group 21)");
  // A coordinate that is not a number: the line of the value.
  const std::string bad_number =
      header_mm() + entities() +
      dxf({{0, "LINE"}, {10, "0"}, {20, "1,5"}, {30, "0"}, {11, "1"}, {21, "0"}, {31, "0"}}) + end_of_file();
  EXPECT_EQ(model_error_message([&] { (void)parse_line_model(bad_number, "model.dxf"); }),
            "model.dxf: line " + std::to_string(line_of(bad_number, "1,5")) + ": group 20: not a finite number: '1,5'");
  // Zero-length LINE.
  const std::string zero = header_mm() + entities() + good +
                           dxf({{0, "LINE"}, {10, "5"}, {20, "5"}, {30, "5"}, {11, "5"}, {21, "5"}, {31, "5"}}) +
                           end_of_file();
  EXPECT_EQ(model_error_message([&] { (void)parse_line_model(zero, "model.dxf"); }),
            "model.dxf: line " + std::to_string(line_of(zero, "LINE", 2)) + ": LINE entity #2: zero-length segment");
  // Unknown units.
  const std::string inches = dxf({{0, "SECTION"}, {2, "HEADER"}, {9, "$INSUNITS"}, {70, "1"}, {0, "ENDSEC"}}) +
                             entities() + good + end_of_file();
  EXPECT_EQ(model_error_message([&] { (void)parse_line_model(inches, "model.dxf"); }),
            "model.dxf: line 8: unknown units: $INSUNITS = 1 (supported: 4 = mm, 6 = m, 0 or absent = mm)");
  // Truncated file, bad group code, no segments, binary DXF.
  EXPECT_EQ(model_error_message([&] { (void)parse_line_model(header_mm() + entities() + good, "model.dxf"); }),
            "model.dxf: line 28: DXF ends early: expected ENDSEC");
  EXPECT_EQ(model_error_message([&] {
              (void)parse_line_model(header_mm() + entities() + "  0\nLINE\nten\n0\n" + end_of_file(), "model.dxf");
            }),
            "model.dxf: line 17: expected a DXF group code (integer 0..1071), got 'ten'");
  EXPECT_EQ(model_error_message([&] {
              (void)parse_line_model(header_mm() + entities() + dxf({{0, "CIRCLE"}}) + end_of_file(), "model.dxf");
            }),
            "model.dxf: DXF has no line segments (LINE, POLYLINE or LWPOLYLINE) in ENTITIES");
  EXPECT_EQ(model_error_message([&] {
              (void)parse_line_model(header_mm() + entities() + good + dxf({{0, "ENDSEC"}}), "model.dxf");
            }),
            "model.dxf: DXF has no '0 / EOF' at the end (truncated?)");
  EXPECT_EQ(model_error_message(
                [&] { (void)parse_line_model(std::string("AutoCAD Binary DXF\r\n\x1a\0", 22), "model.dxf"); }),
            "model.dxf: binary DXF is not supported: save the drawing as ASCII DXF");
  const std::string lw_no_y = entities() + dxf({{0, "LWPOLYLINE"}, {10, "0"}, {20, "0"}, {10, "5"}}) + end_of_file();
  EXPECT_EQ(model_error_message([&] { (void)parse_line_model(lw_no_y, "model.dxf"); }),
            "model.dxf: line 11: LWPOLYLINE entity #1: vertex without y (group 20)");
  // Through the file loader: the message names the path.
  const std::string path = test::write_file("bad-model.dxf", missing);
  EXPECT_THAT(model_error_message([&] { (void)load_line_model(path); }), HasSubstr(path + ": line "));
}

// ---- the planar target has no symmetry ------------------------------------------------------------------

/// Segment sets equal up to order and endpoint order.
bool same_segment_set(const std::vector<Segment3>& a, const std::vector<Segment3>& b) {
  if (a.size() != b.size()) return false;
  constexpr double kTol_m = 1e-9;
  std::vector<bool> used(b.size(), false);
  for (const auto& s : a) {
    bool found = false;
    for (std::size_t j = 0; j < b.size() && !found; ++j) {
      if (used[j]) continue;
      const bool same = ((s.a_m - b[j].a_m).norm() < kTol_m && (s.b_m - b[j].b_m).norm() < kTol_m) ||
                        ((s.a_m - b[j].b_m).norm() < kTol_m && (s.b_m - b[j].a_m).norm() < kTol_m);
      if (same) used[j] = found = true;
    }
    if (!found) return false;
  }
  return true;
}

TEST(LineModelShipped, PlanarTargetHasNoSymmetry) {
  const LineModel m = load_line_model(config_file("target-planar.yaml"));
  // The bounding box is centred on the origin, so the symmetries of the (square hull of the) box act about it.
  Eigen::Vector2d lo(1e9, 1e9);
  Eigen::Vector2d hi = -lo;
  for (const auto& s : m.segments_m) {
    lo = lo.cwiseMin(s.a_m.head<2>()).cwiseMin(s.b_m.head<2>());
    hi = hi.cwiseMax(s.a_m.head<2>()).cwiseMax(s.b_m.head<2>());
  }
  const Eigen::Vector2d centre = (lo + hi) / 2.0;
  EXPECT_LT(centre.norm(), 1e-12);
  struct Symmetry {
    const char* name;
    Eigen::Matrix2d M;
  };
  const std::array<Symmetry, 8> d4 = {{
      {"identity", (Eigen::Matrix2d() << 1, 0, 0, 1).finished()},
      {"rotation 90", (Eigen::Matrix2d() << 0, -1, 1, 0).finished()},
      {"rotation 180", (Eigen::Matrix2d() << -1, 0, 0, -1).finished()},
      {"rotation 270", (Eigen::Matrix2d() << 0, 1, -1, 0).finished()},
      {"mirror x -> -x", (Eigen::Matrix2d() << -1, 0, 0, 1).finished()},
      {"mirror y -> -y", (Eigen::Matrix2d() << 1, 0, 0, -1).finished()},
      {"mirror about y = x", (Eigen::Matrix2d() << 0, 1, 1, 0).finished()},
      {"mirror about y = -x", (Eigen::Matrix2d() << 0, -1, -1, 0).finished()},
  }};
  for (const auto& sym : d4) {
    std::vector<Segment3> moved;
    for (const auto& s : m.segments_m) {
      Segment3 t = s;
      t.a_m.head<2>() = sym.M * (s.a_m.head<2>() - centre) + centre;
      t.b_m.head<2>() = sym.M * (s.b_m.head<2>() - centre) + centre;
      moved.push_back(t);
    }
    const bool is_identity = sym.M.isIdentity();
    EXPECT_EQ(same_segment_set(moved, m.segments_m), is_identity) << sym.name;
  }
  // The test can fail: the outer rectangle alone IS symmetric under the 180 degree rotation.
  std::vector<Segment3> outer(m.segments_m.begin(), m.segments_m.begin() + 4);
  std::vector<Segment3> rotated;
  for (auto s : outer) {
    s.a_m.head<2>() = -s.a_m.head<2>();
    s.b_m.head<2>() = -s.b_m.head<2>();
    rotated.push_back(s);
  }
  EXPECT_TRUE(same_segment_set(rotated, outer));
}

// ---- project_segment --------------------------------------------------------------------------------------

CameraModel pinhole() {
  CameraModel c;
  c.fx = c.fy = 243.2;
  c.cx = 172.5;
  c.cy = 129.5;
  return c;
}

TEST(ProjectSegment, InFrontBehindAndCrossingTheNearPlane) {
  const CameraModel cam = pinhole();
  Pose T;
  T.t_cam_model_m = Eigen::Vector3d(0.0, 0.0, 0.8);
  const Segment3 front{{-0.1, 0.0, 0.0}, {0.1, 0.05, 0.0}};
  const auto s = project_segment(cam, T, front);
  ASSERT_TRUE(s.has_value());
  EXPECT_EQ(s->a_px, *cam.project(T.apply(front.a_m)));
  EXPECT_EQ(s->b_px, *cam.project(T.apply(front.b_m)));
  EXPECT_FALSE(project_segment(cam, T, Segment3{{0, 0, -1.0}, {0.1, 0, -0.9}}).has_value());  // both behind
  // From 0.5 m in front (model z = -0.3) to 0.2 m behind the camera (model z = -1.0): clipped at z = near.
  const Segment3 crossing{{0.05, 0.02, -0.3}, {0.05, 0.02 + 0.7, -1.0}};
  const auto c = project_segment(cam, T, crossing, 0.1);
  ASSERT_TRUE(c.has_value());
  EXPECT_EQ(c->a_px, *cam.project(T.apply(crossing.a_m)));
  // The clipped end is the projection of the point at z = 0.1 m on the segment: (0.05, 0.42, 0.1).
  EXPECT_LT((c->b_px - *cam.project(Eigen::Vector3d(0.05, 0.42, 0.1))).norm(), 1e-9);
  // Same with the ends swapped.
  const auto c2 = project_segment(cam, T, Segment3{crossing.b_m, crossing.a_m}, 0.1);
  ASSERT_TRUE(c2.has_value());
  EXPECT_LT((c2->a_px - c->b_px).norm(), 1e-9);
  EXPECT_EQ(c2->b_px, c->a_px);
}

TEST(ProjectSegment, ShippedModelsInFrontOfTheShippedCamera) {
  // The planar target 0.8 m in front of the camera, facing it, fills the middle of the image.
  const CameraModel cam = load_camera(config_file("davis346.yaml"));
  const LineModel target = load_line_model(config_file("target-planar.yaml"));
  Pose T;
  T.t_cam_model_m = Eigen::Vector3d(0.0, 0.0, 0.8);
  for (const auto& seg : target.segments_m) {
    const auto s = project_segment(cam, T, seg);
    ASSERT_TRUE(s.has_value());
    EXPECT_TRUE(cam.in_image(s->a_px));
    EXPECT_TRUE(cam.in_image(s->b_px));
  }
}

}  // namespace
}  // namespace evpipe::camera
