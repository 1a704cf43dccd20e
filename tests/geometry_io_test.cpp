// Mesh file input/output: writer/reader round trips, every reader on small files covering the
// format variants users meet, and the whole corpus under ../shared/data.
#include "geometry/errors.h"
#include "geometry/mesh_io.h"
#include "geometry/read_points.h"
#include "geometry/thesis_format.h"
#include "test_common.h"

#include <catch2/catch.hpp>

#include <cstdint>
#include <cstring>
#include <fstream>
#include <map>

using namespace fascicle;
using fascicle::test::TempDir;

namespace {

void write_bytes(const std::string& path, const std::string& content) {
  std::ofstream out(path, std::ios::binary);
  out.write(content.data(), static_cast<std::streamsize>(content.size()));
  REQUIRE(out.good());
}

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

/// Appends `value` to `out` in little (or big) endian byte order.
template <class T>
void put(std::string& out, T value, bool big_endian = false) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  if (big_endian)
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(bytes[i], bytes[sizeof(T) - 1 - i]);
  out.append(bytes, sizeof(T));
}

/// A tetrahedron with coordinates that need all 17 digits to survive a text round trip.
TriangleMesh awkward_tetrahedron() {
  TriangleMesh m;
  m.positions = {Vec3(0.1, 1.0 / 3.0, -2.5e-7), Vec3(12345.678901234567, -0.2, 1e-300),
                 Vec3(-7.0 / 11.0, 2.0 / 3.0, 123456789.123), Vec3(3.0e10, -1.0 / 7.0, 0.0)};
  m.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  return m;
}

std::vector<std::vector<int>> polygons_of(const TriangleMesh& mesh) {
  std::vector<std::vector<int>> polygons;
  for (const auto& t : mesh.triangles) polygons.push_back({t[0], t[1], t[2]});
  return polygons;
}

using Polys = std::vector<std::vector<int>>;

}  // namespace

// ---------------------------------------------------------------------------------------------
// Round trips

TEST_CASE("text and double writers round-trip a mesh exactly", "[geometry][io]") {
  TempDir dir;
  const TriangleMesh mesh = awkward_tetrahedron();
  for (const std::string ext : {"off", "obj", "ply", "vtk", "OFF"}) {
    INFO(ext);
    const std::string path = dir.file("mesh." + ext);
    write_triangle_mesh(path, mesh);
    const PolygonSoup soup = read_polygon_soup(path);
    REQUIRE(soup.points.size() == mesh.positions.size());
    for (std::size_t i = 0; i < soup.points.size(); ++i) CHECK(soup.points[i] == mesh.positions[i]);
    CHECK(soup.polygons == polygons_of(mesh));
  }
}

TEST_CASE("binary STL round-trips within float precision", "[geometry][io]") {
  TempDir dir;
  const TriangleMesh mesh = awkward_tetrahedron();
  const std::string path = dir.file("mesh.stl");
  write_triangle_mesh(path, mesh);
  const std::string bytes = read_bytes(path);
  REQUIRE(bytes.size() == 84 + 50 * mesh.triangles.size());
  CHECK(bytes.substr(0, 5) != "solid");
  const PolygonSoup soup = read_polygon_soup(path);
  REQUIRE(soup.points.size() == 3 * mesh.triangles.size());
  REQUIRE(soup.polygons.size() == mesh.triangles.size());
  for (std::size_t f = 0; f < mesh.triangles.size(); ++f) {
    CHECK(soup.polygons[f] == std::vector<int>{int(3 * f), int(3 * f + 1), int(3 * f + 2)});
    for (int k = 0; k < 3; ++k) {
      const Vec3& expected = mesh.positions[static_cast<std::size_t>(mesh.triangles[f][static_cast<std::size_t>(k)])];
      for (int c = 0; c < 3; ++c)
        CHECK(soup.points[3 * f + static_cast<std::size_t>(k)][c] ==
              static_cast<double>(static_cast<float>(expected[c])));
    }
  }
  // The stored normal of the first facet is the unit normal of its triangle.
  float normal[3];
  std::memcpy(normal, bytes.data() + 84, 12);
  const Vec3 a = mesh.positions[0], b = mesh.positions[2], c = mesh.positions[1];
  const Vec3 n = (b - a).cross(c - a).normalized();
  for (int i = 0; i < 3; ++i) CHECK(normal[i] == Approx(n[i]).margin(1e-6));
}

TEST_CASE("binary STL refuses a mesh whose corners single precision would merge, and writes nothing", "[geometry][io]") {
  TempDir dir;
  TriangleMesh mesh;  // a 0.1 mm tetrahedron 10 km from the origin, in mm: float32 steps by 1 there
  mesh.positions = {Vec3(0, 0, 0), Vec3(0.1, 0, 0), Vec3(0, 0.1, 0), Vec3(0, 0, 0.1)};
  for (Vec3& p : mesh.positions) p += Vec3::Constant(1e7);
  mesh.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  const std::string path = dir.file("mesh.stl");
  try {
    write_triangle_mesh(path, mesh);
    FAIL("expected IoError");
  } catch (const IoError& e) {
    CHECK(std::string(e.what()).find("single-precision") != std::string::npos);
  }
  CHECK_FALSE(std::filesystem::exists(path));
  write_triangle_mesh(dir.file("mesh.off"), mesh);  // double precision keeps them apart
  CHECK(read_polygon_soup(dir.file("mesh.off")).points.size() == mesh.positions.size());
}

TEST_CASE("writers refuse an unknown extension before writing anything", "[geometry][io]") {
  TempDir dir;
  const std::string path = dir.file("mesh.xyz");
  try {
    write_triangle_mesh(path, awkward_tetrahedron());
    FAIL("no exception");
  } catch (const InputError& e) {
    CHECK(e.code() == ErrorCode::unknown_format);
    CHECK(std::string(e.what()).find(path) != std::string::npos);
  }
  CHECK_FALSE(std::filesystem::exists(path));
  Polylines lines;
  lines.lines = {{Vec3(0, 0, 0), Vec3(1, 0, 0)}};
  CHECK_THROWS_AS(write_polylines(dir.file("fibres.ply"), lines), InputError);
  CHECK_FALSE(std::filesystem::exists(dir.file("fibres.ply")));
  CHECK(std::distance(std::filesystem::directory_iterator(dir.path()), std::filesystem::directory_iterator()) == 0);
}

TEST_CASE("writers report an unwritable target as IoError and keep an existing file", "[geometry][io]") {
  TempDir dir;
  const TriangleMesh mesh = awkward_tetrahedron();
  try {
    write_triangle_mesh(dir.file("missing-folder/mesh.off"), mesh);
    FAIL("no exception");
  } catch (const IoError& e) { CHECK(e.code() == ErrorCode::output_failed); }
  const std::string path = dir.file("mesh.obj");
  write_bytes(path, "old content");
  TriangleMesh broken = mesh;
  broken.triangles.push_back({0, 1, 99});  // out of range: refused before anything is written
  CHECK_THROWS_AS(write_triangle_mesh(path, broken), Error);
  CHECK(read_bytes(path) == "old content");
}

TEST_CASE("polylines round-trip through VTK (with cell data) and OBJ", "[geometry][io]") {
  TempDir dir;
  Polylines lines;
  lines.lines = {{Vec3(0.1, 0.2, 0.3), Vec3(1.0 / 3.0, 2, 3), Vec3(4, 5, 6.000000000000001)},
                 {Vec3(-1, -2, -3), Vec3(7, 8, 9)},
                 {Vec3(1e-9, 1e9, 0.5), Vec3(2, 2, 2), Vec3(3, 3, 3), Vec3(4, 4, 4)}};
  lines.cell_data = {{"length", {1.5, 2.0 / 3.0, 3.25}}, {"fibre id", {0, 1, 2}}};

  const std::string vtk = dir.file("fibres.vtk");
  write_polylines(vtk, lines);
  const std::string text = read_bytes(vtk);
  CHECK(text.find("LINES 3 12\n") != std::string::npos);
  CHECK(text.find("CELL_DATA 3\n") != std::string::npos);
  // One FIELD block with every array (VTK's default readers keep only the first SCALARS block);
  // integer arrays as int, the others as double; blanks are not allowed in VTK names.
  CHECK(text.find("FIELD FieldData 2\nlength 1 3 double\n") != std::string::npos);
  CHECK(text.find("fibre_id 1 3 int\n0\n1\n2\n") != std::string::npos);
  const Polylines back = read_polylines(vtk);
  CHECK(back.lines == lines.lines);
  REQUIRE(back.cell_data.size() == 2);
  CHECK(back.cell_data[0].name == "length");
  CHECK(back.cell_data[0].values == lines.cell_data[0].values);
  CHECK(back.cell_data[1].name == "fibre_id");
  CHECK(back.cell_data[1].values == lines.cell_data[1].values);
  // The file is also valid polydata for the mesh reader's grammar (no faces: file_empty).
  CHECK_THROWS_AS(read_polygon_soup(vtk), InputError);

  const std::string obj = dir.file("fibres.obj");
  write_polylines(obj, lines);
  const Polylines back_obj = read_polylines(obj);
  CHECK(back_obj.lines == lines.lines);
  CHECK(back_obj.cell_data.empty());

  // .vtp and .vtu keep the arrays too, the integer one as Int32; a .vtu holds poly-line cells.
  for (const char* ext : {"vtp", "vtu"}) {
    CAPTURE(ext);
    const std::string xml = dir.file(std::string("fibres.") + ext);
    write_polylines(xml, lines);
    const std::string xml_text = read_bytes(xml);
    CHECK(xml_text.find("<DataArray type=\"Int32\" Name=\"fibre id\"") != std::string::npos);
    CHECK(xml_text.find("<DataArray type=\"Float64\" Name=\"length\"") != std::string::npos);
    const Polylines back_xml = read_polylines(xml);
    CHECK(back_xml.lines == lines.lines);
    REQUIRE(back_xml.cell_data.size() == 2);
    CHECK(back_xml.cell_data[0].values == lines.cell_data[0].values);
    CHECK(back_xml.cell_data[1].values == lines.cell_data[1].values);
  }
  // The .vtu holds one line cell per segment (2 + 1 + 3) with the fibre's number per cell.
  const std::string vtu_text = read_bytes(dir.file("fibres.vtu"));
  CHECK(vtu_text.find("NumberOfCells=\"6\"") != std::string::npos);
  CHECK(vtu_text.find("Name=\"fibre\"") != std::string::npos);

  // A legacy file with the older layout (one SCALARS block per array) still reads.
  const std::string old = dir.file("old.vtk");
  std::ofstream(old) << "# vtk DataFile Version 3.0\nold\nASCII\nDATASET POLYDATA\nPOINTS 2 double\n0 0 0 1 1 1\n"
                        "LINES 1 3\n2 0 1\nCELL_DATA 1\nSCALARS fibre_r double 1\nLOOKUP_TABLE default\n4\n"
                        "SCALARS fibre_s int 1\nLOOKUP_TABLE default\n5\n";
  const Polylines back_old = read_polylines(old);
  REQUIRE(back_old.cell_data.size() == 2);
  CHECK(back_old.cell_data[0].values == std::vector<double>{4.0});
  CHECK(back_old.cell_data[1].values == std::vector<double>{5.0});
}

TEST_CASE("thesis format round trip", "[geometry][io]") {
  TempDir dir;
  ThesisModel model;
  model.points = {Vec3(0, 0, 0), Vec3(1.0 / 3.0, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1), Vec3(0.25, 0.25, 0.1)};
  model.surface = {1, 1, 1, 1, 0};
  model.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  model.springs = {{0, 4, 1.5}, {1, 4, 2.0 / 3.0}, {2, 4, 1.0}, {3, 4, 1e-3}};
  model.fibres = {{0, 3}, {1, 2}};
  model.origin = {0, 1};
  model.insertion = {3};
  const std::string path = dir.file("model.txt");
  write_thesis_model(path, model);
  const ThesisModel back = read_thesis_model(path);
  CHECK(back.points == model.points);
  CHECK(back.surface == model.surface);
  CHECK(back.triangles == model.triangles);
  REQUIRE(back.springs.size() == model.springs.size());
  for (std::size_t i = 0; i < model.springs.size(); ++i) {
    CHECK(back.springs[i].a == model.springs[i].a);
    CHECK(back.springs[i].b == model.springs[i].b);
    CHECK(back.springs[i].stiffness == model.springs[i].stiffness);
  }
  CHECK(back.fibres == model.fibres);
  CHECK(back.origin == model.origin);
  CHECK(back.insertion == model.insertion);
  CHECK(read_bytes(path).substr(0, 4) == "5 4\n");

  const PolygonSoup soup = read_polygon_soup(path);
  CHECK(soup.points == model.points);
  CHECK(soup.polygons == Polys{{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}});
}

TEST_CASE("mesh format from the extension", "[geometry][io]") {
  CHECK(mesh_format_from_path("a/b.OFF") == MeshFormat::off);
  CHECK(mesh_format_from_path("x.obj") == MeshFormat::obj);
  CHECK(mesh_format_from_path("x.Stl") == MeshFormat::stl);
  CHECK(mesh_format_from_path("x.ply") == MeshFormat::ply);
  CHECK(mesh_format_from_path("x.vtk") == MeshFormat::vtk);
  CHECK(mesh_format_from_path("x.txt") == MeshFormat::thesis);
  CHECK_THROWS_AS(mesh_format_from_path("x.vtp"), InputError);
  CHECK_THROWS_AS(mesh_format_from_path("noextension"), InputError);
}

// ---------------------------------------------------------------------------------------------
// OFF

TEST_CASE("OFF variants: glued header, comments, COFF/NOFF extras, face colours, short faces", "[geometry][io][off]") {
  TempDir dir;
  const Polys square = {{0, 1, 2, 3}};
  SECTION("header glued to the counts, comment on the counts line") {
    write_bytes(dir.file("a.off"), "\t  OFF4 1 0 # counts\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n");
    const PolygonSoup s = read_polygon_soup(dir.file("a.off"));
    CHECK(s.points.size() == 4);
    CHECK(s.points[2] == Vec3(1, 1, 0));
    CHECK(s.polygons == square);
  }
  SECTION("comments, blank lines, counts on their own line, CRLF") {
    write_bytes(dir.file("a.off"),
                "OFF\r\n# c\r\n\r\n4 1 4\r\n0 0 0 # a vertex\r\n1 0 0\r\n\r\n1 1 0\r\n0 1 0\r\n# f\r\n4 0 1 2 3\r\n");
    const PolygonSoup s = read_polygon_soup(dir.file("a.off"));
    CHECK(s.points[1] == Vec3(1, 0, 0));
    CHECK(s.polygons == square);
  }
  SECTION("COFF / NOFF extra vertex values and face colours are ignored") {
    write_bytes(dir.file("c.off"),
                "NCOFF\n4 2 0\n0 0 0 0 0 1 255 0 0 255\n1 0 0 0 0 1 1 1 1 1\n1 1 0 0 0 1 1 1 1 1\n"
                "0 1 0 0 0 1 1 1 1 1\n3 0 1 2 1.0 0.0 0.0 0.75\n3 0 2 3\n");
    const PolygonSoup s = read_polygon_soup(dir.file("c.off"));
    CHECK(s.points == std::vector<Vec3>{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0)});
    CHECK(s.polygons == Polys{{0, 1, 2}, {0, 2, 3}});
  }
  SECTION("numbers below the double range read as zero; exponents, signs and no leading digit") {
    write_bytes(dir.file("u.off"), "OFF\n3 1 0\n1e-400 -1E-999 +.5\n-0.25e+1 1. 7E2\n0 0 0\n3 0 1 2\n");
    const PolygonSoup s = read_polygon_soup(dir.file("u.off"));
    CHECK(s.points[0] == Vec3(0, 0, 0.5));
    CHECK(s.points[1] == Vec3(-2.5, 1, 700));
  }
  SECTION("no header word; faces with two indices or repeated indices are kept as stored") {
    write_bytes(dir.file("d.off"), "3 3 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n2 0 1\n3 0 0 1\n");
    const PolygonSoup s = read_polygon_soup(dir.file("d.off"));
    CHECK(s.polygons == Polys{{0, 1, 2}, {0, 1}, {0, 0, 1}});
  }
}

TEST_CASE("a UTF-8 byte order mark does not hide the first statement", "[geometry][io]") {
  TempDir dir;
  const std::string bom = "\xEF\xBB\xBF";
  write_bytes(dir.file("b.obj"), bom + "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  CHECK(read_polygon_soup(dir.file("b.obj")).points.size() == 3);
  write_bytes(dir.file("b.off"), bom + "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  CHECK(read_polygon_soup(dir.file("b.off")).polygons == Polys{{0, 1, 2}});
  write_bytes(dir.file("b.stl"), bom +
                                     "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
                                     "vertex 0 1 0\nendloop\nendfacet\nendsolid x\n");
  CHECK(read_polygon_soup(dir.file("b.stl")).polygons == Polys{{0, 1, 2}});
  write_bytes(dir.file("b.xyz"), bom + "1 2 3\n");
  CHECK(read_points(dir.file("b.xyz")) == std::vector<Vec3>{Vec3(1, 2, 3)});
}

// ---------------------------------------------------------------------------------------------
// OBJ

TEST_CASE("OBJ: slashes, negative indices, continuations, other statements ignored", "[geometry][io][obj]") {
  TempDir dir;
  const std::string text =
      "# comment\nmtllib x.mtl\no thing\n"
      "v 0 0 0\nv 1 0 0 1.0\nv 1 1 0 0.5 0.5 0.5\nv 0 1 0\n"
      "vt 0 0\nvt 1 0\nvn 0 0 1\ng group\nusemtl m\ns off\n"
      "f 1/1/1 2/2/1 3//1\n"
      "f -4 -2 -1\n"
      "f 1 2 \\\r\n 3 \\\n 4\n"
      "l 1 2 3\n"
      "f 1// 2//\n"
      "v 5 5 5\n"
      "f -1 1 2\n";
  write_bytes(dir.file("m.obj"), text);
  const PolygonSoup s = read_polygon_soup(dir.file("m.obj"));
  REQUIRE(s.points.size() == 5);
  CHECK(s.points[4] == Vec3(5, 5, 5));
  CHECK(s.polygons == Polys{{0, 1, 2}, {0, 2, 3}, {0, 1, 2, 3}, {0, 1}, {4, 0, 1}});
  const Polylines lines = read_polylines(dir.file("m.obj"));
  REQUIRE(lines.lines.size() == 1);
  CHECK(lines.lines[0] == std::vector<Vec3>{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0)});
}

// ---------------------------------------------------------------------------------------------
// STL

TEST_CASE("ASCII STL, several solids, loose case and layout", "[geometry][io][stl]") {
  TempDir dir;
  write_bytes(dir.file("a.stl"),
              "solid one\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n   vertex 0 1 0\n"
              "  endloop\n endfacet\nendsolid one\n"
              "SOLID two\nFACET NORMAL nan 0 0 OUTER LOOP VERTEX 0 0 1 VERTEX 1 0 1\r\nVERTEX 0 1 1.5e0 ENDLOOP "
              "ENDFACET\nENDSOLID\n");
  const PolygonSoup s = read_polygon_soup(dir.file("a.stl"));
  REQUIRE(s.points.size() == 6);
  CHECK(s.points[5] == Vec3(0, 1, 1.5));
  CHECK(s.polygons == Polys{{0, 1, 2}, {3, 4, 5}});
}

TEST_CASE("binary STL, also when its header starts with 'solid'", "[geometry][io][stl]") {
  TempDir dir;
  for (const std::string header : {"solid looks like ascii", "plain binary header"}) {
    INFO(header);
    std::string bytes = header;
    bytes.resize(80, ' ');
    put<std::uint32_t>(bytes, 2);
    const float v[2][3][3] = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{0, 0, 1}, {1, 0, 1}, {0, 1, 1.25f}}};
    for (const auto& facet : v) {
      for (int i = 0; i < 3; ++i) put<float>(bytes, 0.0f);
      for (const auto& p : facet)
        for (float c : p) put<float>(bytes, c);
      put<std::uint16_t>(bytes, 0);
    }
    write_bytes(dir.file("b.stl"), bytes);
    const PolygonSoup s = read_polygon_soup(dir.file("b.stl"));
    REQUIRE(s.points.size() == 6);
    CHECK(s.points[5] == Vec3(0, 1, 1.25));
    CHECK(s.polygons == Polys{{0, 1, 2}, {3, 4, 5}});
  }
}

// ---------------------------------------------------------------------------------------------
// PLY

namespace {

/// A binary PLY with int16 x, double y, float z, an extra uchar and a list property on the
/// vertices, a face element with an extra list before the indices, and a `material` element.
std::string binary_ply(bool big) {
  std::string h = std::string("ply\nformat ") + (big ? "binary_big_endian" : "binary_little_endian") +
                  " 1.0\ncomment test\nobj_info extra\nelement vertex 4\nproperty short x\nproperty double y\n"
                  "property float z\nproperty uchar red\nproperty list uchar float extra\n"
                  "element face 2\nproperty list uchar short texcoord_ids\nproperty list uint int "
                  "vertex_index\nproperty int flags\n"
                  "element material 1\nproperty list int uchar name\nend_header\n";
  const double p[4][3] = {{0, 0.5, 0.25}, {1, 0, 0}, {1, 1, 0}, {-3, 1, 0}};
  for (const auto& v : p) {
    put<std::int16_t>(h, static_cast<std::int16_t>(v[0]), big);
    put<double>(h, v[1], big);
    put<float>(h, static_cast<float>(v[2]), big);
    put<std::uint8_t>(h, 200);
    put<std::uint8_t>(h, 2);
    put<float>(h, 1.0f, big);
    put<float>(h, 2.0f, big);
  }
  const std::vector<std::vector<int>> faces = {{0, 1, 2}, {0, 2, 3, 1}};
  for (const auto& f : faces) {
    put<std::uint8_t>(h, 1);
    put<std::int16_t>(h, 7, big);
    put<std::uint32_t>(h, static_cast<std::uint32_t>(f.size()), big);
    for (int i : f) put<std::int32_t>(h, i, big);
    put<std::int32_t>(h, 99, big);
  }
  put<std::int32_t>(h, 3, big);
  h += "abc";
  return h;
}

}  // namespace

TEST_CASE("PLY binary little and big endian with mixed types and extra properties", "[geometry][io][ply]") {
  TempDir dir;
  for (bool big : {false, true}) {
    INFO(big);
    write_bytes(dir.file("b.ply"), binary_ply(big));
    const PolygonSoup s = read_polygon_soup(dir.file("b.ply"));
    CHECK(s.points == std::vector<Vec3>{Vec3(0, 0.5, 0.25), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(-3, 1, 0)});
    CHECK(s.polygons == Polys{{0, 1, 2}, {0, 2, 3, 1}});
  }
}

TEST_CASE("PLY ASCII with extra elements and properties", "[geometry][io][ply]") {
  TempDir dir;
  write_bytes(
      dir.file("a.ply"),
      "ply\r\nformat ascii 1.0\r\ncomment hi\r\nelement vertex 3\r\nproperty float x\r\nproperty float y\r\n"
      "property float z\r\nproperty float confidence\r\nelement face 2\r\nproperty list uchar int vertex_indices\r\n"
      "property uchar red\r\nelement edge 1\r\nproperty int a\r\nproperty int b\r\nend_header\r\n"
      "0 0 0 0.5\r\n1 0 0 0.5\r\n0 1 -2.5e-1 1\r\n3 0 1 2 255\r\n2 1 2 0\r\n0 1\r\n");
  const PolygonSoup s = read_polygon_soup(dir.file("a.ply"));
  CHECK(s.points[2] == Vec3(0, 1, -0.25));
  CHECK(s.polygons == Polys{{0, 1, 2}, {1, 2}});
}

TEST_CASE("PLY tristrips: restarts at -1, alternating winding, degenerate triangles kept", "[geometry][io][ply]") {
  TempDir dir;
  const std::string header_ascii =
      "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\nproperty float z\n"
      "element tristrips 1\nproperty list int int vertex_indices\nend_header\n"
      "0 0 0\n1 0 0\n0 1 0\n1 1 0\n0 2 0\n1 2 0\n";
  // Strip 0 1 2 3 4, restart, strip 5 4 3 3 2 (a repeated index gives degenerate triangles).
  write_bytes(dir.file("s.ply"), header_ascii + "11 0 1 2 3 4 -1 5 4 3 3 2\n");
  const Polys expected = {{0, 1, 2}, {2, 1, 3}, {2, 3, 4}, {5, 4, 3}, {3, 4, 3}, {3, 3, 2}};
  CHECK(read_polygon_soup(dir.file("s.ply")).polygons == expected);

  std::string bin =
      "ply\nformat binary_big_endian 1.0\nelement vertex 6\nproperty float x\nproperty float y\nproperty float z\n"
      "element tristrips 1\nproperty list int int vertex_indices\nend_header\n";
  for (int i = 0; i < 6; ++i) {
    put<float>(bin, static_cast<float>(i % 2), true);
    put<float>(bin, static_cast<float>(i / 2), true);
    put<float>(bin, 0.0f, true);
  }
  const std::vector<int> strip = {0, 1, 2, 3, 4, -1, 5, 4, 3, 3, 2};
  put<std::int32_t>(bin, static_cast<std::int32_t>(strip.size()), true);
  for (int i : strip) put<std::int32_t>(bin, i, true);
  write_bytes(dir.file("sb.ply"), bin);
  const PolygonSoup s = read_polygon_soup(dir.file("sb.ply"));
  CHECK(s.polygons == expected);
  CHECK(s.points[5] == Vec3(1, 2, 0));
}

// ---------------------------------------------------------------------------------------------
// VTK

TEST_CASE("VTK ASCII: blank line after the title, all cell kinds, attributes after the geometry",
          "[geometry][io][vtk]") {
  TempDir dir;
  write_bytes(dir.file("a.vtk"),
              "# vtk DataFile Version 3.0\nmy title\n\nASCII\nDATASET POLYDATA\n"
              "FIELD FieldData 1\nTIME 1 1 double\n0.5\n"
              "POINTS 6 float\n0 0 0 1 0 0 0 1 0\n1 1 0 0 2 0 1 2.5 0\n"
              "VERTICES 1 2\n1 0\n"
              "LINES 1 3\n2 0 5\n"
              "POLYGONS 2 9\n3 0 1 2\n4 1 3 4 2\n"
              "TRIANGLE_STRIPS 1 5\n4 2 3 4 5\n"
              "CELL_DATA 5\nSCALARS id int 1\nLOOKUP_TABLE default\n10 11 12 13 14\n"
              "POINT_DATA 6\nNORMALS n float\n0 0 1 0 0 1 0 0 1 0 0 1 0 0 1 0 0 1\n");
  const PolygonSoup s = read_polygon_soup(dir.file("a.vtk"));
  REQUIRE(s.points.size() == 6);
  CHECK(s.points[5] == Vec3(1, 2.5, 0));
  CHECK(s.polygons == Polys{{0, 1, 2}, {1, 3, 4, 2}, {2, 3, 4}, {4, 3, 5}});
  const Polylines lines = read_polylines(dir.file("a.vtk"));
  REQUIRE(lines.lines.size() == 1);
  CHECK(lines.lines[0] == std::vector<Vec3>{Vec3(0, 0, 0), Vec3(1, 2.5, 0)});
  REQUIRE(lines.cell_data.size() == 1);
  CHECK(lines.cell_data[0].name == "id");
  CHECK(lines.cell_data[0].values == std::vector<double>{11});  // the value of the LINES cell
}

TEST_CASE("VTK 5.1 OFFSETS/CONNECTIVITY cells", "[geometry][io][vtk]") {
  TempDir dir;
  write_bytes(dir.file("n.vtk"),
              "# vtk DataFile Version 5.1\nnew\nASCII\nDATASET POLYDATA\nPOINTS 4 double\n0 0 0 1 0 0 0 1 0 1 1 0\n"
              "METADATA\nINFORMATION 0\n\n"
              "POLYGONS 3 7\nOFFSETS vtktypeint64\n0 3 7\nCONNECTIVITY vtktypeint64\n0 1 2 1 3 2 0\n");
  CHECK(read_polygon_soup(dir.file("n.vtk")).polygons == Polys{{0, 1, 2}, {1, 3, 2, 0}});
}

TEST_CASE("VTK 5.1 binary OFFSETS/CONNECTIVITY with 64-bit indices", "[geometry][io][vtk]") {
  TempDir dir;
  std::string s = "# vtk DataFile Version 5.1\nnew\nBINARY\nDATASET POLYDATA\nPOINTS 4 float\n";
  for (int v = 0; v < 4; ++v)
    for (int c = 0; c < 3; ++c) put<float>(s, static_cast<float>(v == c + 1), true);
  s += "\nPOLYGONS 3 7\nOFFSETS vtktypeint64\n";
  for (std::int64_t o : {0, 3, 7}) put<std::int64_t>(s, o, true);
  s += "\nCONNECTIVITY vtktypeint64\n";
  for (std::int64_t i : {0, 1, 2, 1, 3, 2, 0}) put<std::int64_t>(s, i, true);
  s += "\nTRIANGLE_STRIPS 2 4\nOFFSETS vtktypeint32\n";
  for (std::int32_t o : {0, 4}) put<std::int32_t>(s, o, true);
  s += "\nCONNECTIVITY vtktypeint32\n";
  for (std::int32_t i : {0, 1, 2, 3}) put<std::int32_t>(s, i, true);
  s += "\n";
  write_bytes(dir.file("n.vtk"), s);
  const PolygonSoup soup = read_polygon_soup(dir.file("n.vtk"));
  CHECK(soup.points[3] == Vec3(0, 0, 1));
  CHECK(soup.polygons == Polys{{0, 1, 2}, {1, 3, 2, 0}, {0, 1, 2}, {2, 1, 3}});
}

namespace {

/// A binary VTK polydata in the ALBA layout (blank line after the title), big endian.
std::string binary_vtk(bool double_points) {
  std::string s = "# vtk DataFile Version 3.0\n# ALBA data file - albaVMEItemVTK output\n\nBINARY\nDATASET POLYDATA\n";
  s += std::string("POINTS 5 ") + (double_points ? "double" : "float") + "\n";
  const float p[5][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}, {0.5f, 2, 0.25f}};
  for (const auto& v : p)
    for (float c : v) {
      if (double_points)
        put<double>(s, c, true);
      else
        put<float>(s, c, true);
    }
  s += "\nPOLYGONS 2 8\n";
  for (int i : {3, 0, 1, 2, 3, 1, 3, 2}) put<std::int32_t>(s, i, true);
  s += "\nTRIANGLE_STRIPS 1 4\n";
  for (int i : {3, 2, 3, 4}) put<std::int32_t>(s, i, true);
  s += "\nCELL_DATA 3\nPOINT_DATA 5\n";
  return s;
}

}  // namespace

TEST_CASE("VTK BINARY (big endian) with float and double points and strips", "[geometry][io][vtk]") {
  TempDir dir;
  for (bool dbl : {false, true}) {
    INFO(dbl);
    write_bytes(dir.file("b.vtk"), binary_vtk(dbl));
    const PolygonSoup s = read_polygon_soup(dir.file("b.vtk"));
    REQUIRE(s.points.size() == 5);
    CHECK(s.points[4] == Vec3(0.5, 2, 0.25));
    CHECK(s.polygons == Polys{{0, 1, 2}, {1, 3, 2}, {2, 3, 4}});
  }
}

// ---------------------------------------------------------------------------------------------
// Landmarks

TEST_CASE("landmark points with comments and blank lines", "[geometry][io]") {
  TempDir dir;
  write_bytes(dir.file("p.xyz"), "# origin\n\n 1.5 2 -3 \n# more\n4e1\t5 6 # trailing comment\r\n");
  CHECK(read_points(dir.file("p.xyz")) == std::vector<Vec3>{Vec3(1.5, 2, -3), Vec3(40, 5, 6)});
}

// ---------------------------------------------------------------------------------------------
// Corpus

namespace {

/// Corpus files that are not valid meshes, with the reason (none found so far: every mesh file
/// under ../shared/data reads).
const std::map<std::string, std::string> invalid_corpus_files = {};

}  // namespace

TEST_CASE("every corpus mesh reads with faces", "[geometry][io][corpus]") {
  FASCICLE_REQUIRE_DATA();
  std::vector<std::string> files;
  for (const char* sub : {"muscles", "bones", "broken"})
    for (const auto& f : test::corpus_files(sub, {"off", "obj", "stl", "ply", "vtk"})) files.push_back(f);
  CHECK(files.size() >= 112);
  for (const auto& file : files) {
    INFO(file);
    const std::string name = std::filesystem::path(file).filename().string();
    if (invalid_corpus_files.count(name) != 0) {
      CHECK_THROWS_AS(read_polygon_soup(file), InputError);
      continue;
    }
    PolygonSoup soup;
    REQUIRE_NOTHROW(soup = read_polygon_soup(file));
    CHECK(!soup.points.empty());
    CHECK(!soup.polygons.empty());
  }
}

TEST_CASE("corpus: LHDL muscle counts, PLY strips, parser edge cases", "[geometry][io][corpus]") {
  FASCICLE_REQUIRE_DATA();
  const std::string root = test::data_dir();
  struct Expected {
    const char* path;
    std::size_t points, faces;
  };
  // Counts from ../shared/data/MANIFEST.md (V / F as stored).
  const Expected expected[] = {
      {"muscles/lhdl/LHDL_R_M081_GluteusMaximus_smooth.312.vtk", 7502, 15000},
      {"muscles/lhdl/LHDL_R_M082_GluteusMedius_smooth.334.vtk", 4002, 7980},
      {"muscles/lhdl/LHDL_R_M090_Psoas_smooth.415.vtk", 4001, 7946},
      {"muscles/lhdl/LHDL_R_M091_Iliacus_smooth.365.vtk", 4002, 7966},
      {"bones/lhdl/LHDL_R_Femur_CT.123.vtk", 42502, 84998},
      {"broken/meshlab-sample/brain.ply", 18844, 36752},
      {"broken/meshlab-sample/hippo.ply", 23105, 46202},
      {"broken/meshlab-sample/elephant.ply", 19753, 39290},
      {"broken/trimesh-models/bunny.ply", 8171, 16301},
      {"broken/trimesh-models/whitespace.off", 8, 6},
      {"broken/trimesh-models/comments.off", 8, 6},
      {"broken/trimesh-models/wallhole.obj", 92, 13},
      {"broken/trimesh-models/negative_indices.obj", 8, 6},
      {"broken/trimesh-models/notenoughindices.obj", 3, 2},
      {"broken/cgal-pmp-testdata/data_repair/nm_edges_simple.off", 12, 8},
      {"broken/meshlab-sample/office_chair.obj", 3476, 3391},
      {"broken/trimesh-models/multibody.stl", 96, 32},
      {"muscles/opendihu/left_biceps_brachii.stl", 17856, 5952},
      {"muscles/visible-human/VHM_Left/VHM_Left_Muscle_GluteusMaximus_smooth.stl", 178338, 59446},
      {"broken/trimesh-models/octagonal_pocket.stl", 9786, 3262},  // binary, header starts with "solid"
  };
  for (const auto& e : expected) {
    INFO(e.path);
    const PolygonSoup soup = read_polygon_soup(root + "/" + e.path);
    CHECK(soup.points.size() == e.points);
    CHECK(soup.polygons.size() == e.faces);
  }
  // Strip files give triangles only.
  for (const char* strips : {"brain.ply", "hippo.ply", "elephant.ply"}) {
    const PolygonSoup soup = read_polygon_soup(root + "/broken/meshlab-sample/" + strips);
    for (const auto& p : soup.polygons) CHECK(p.size() == 3);
  }
  const PolygonSoup glute = read_polygon_soup(root + "/muscles/lhdl/LHDL_R_M081_GluteusMaximus_smooth.312.vtk");
  for (const auto& p : glute.polygons) CHECK(p.size() == 3);
  // wallhole.obj: the second face continues over a `\` line: 7 + 4 corners.
  CHECK(read_polygon_soup(root + "/broken/trimesh-models/wallhole.obj").polygons[1].size() == 11);
  // negative_indices.obj: "f -8/-13/-6 -4/-12/-6 -2/-12/-6 -6/-11/-6" with 8 vertices.
  CHECK(read_polygon_soup(root + "/broken/trimesh-models/negative_indices.obj").polygons[0] ==
        std::vector<int>{0, 4, 6, 2});
}

TEST_CASE("corpus: landmark files", "[geometry][io][corpus]") {
  FASCICLE_REQUIRE_DATA();
  const auto files = test::corpus_files("muscles", {"xyz"});
  CHECK(files.size() == 9);
  for (const auto& file : files) {
    INFO(file);
    const std::vector<Vec3> points = read_points(file);
    CHECK(!points.empty());
  }
  const auto origin = read_points(test::data_dir() + "/muscles/lhdl/LHDL_R_M081_GluteusMaximus.origin.xyz");
  CHECK(origin.front() == Vec3(175.3240, 297.0010, -307.4670));
}
