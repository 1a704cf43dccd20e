// Polyline files: round trips through .vtk, .vtp, .obj and .csv with exact doubles and the
// lattice arrays, and one-line errors with codes and line numbers for malformed .vtp and .csv.
#include "geometry/errors.h"
#include "geometry/mesh_io.h"
#include "test_common.h"

#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

using namespace fascicle;
using fascicle::test::TempDir;
using test::read_text;

namespace {

/// Values that need all 17 significant digits, plus extremes.
Polylines awkward_fibres() {
  Polylines lines;
  lines.lines = {{Vec3(0.1, 0.2, 0.3), Vec3(1.0 / 3.0, -2.0 / 7.0, 3), Vec3(4, 5, 6.000000000000001)},
                 {Vec3(-1e-300, 1e300, -0.0), Vec3(std::nextafter(1.0, 2.0), std::numeric_limits<double>::min(), 9)},
                 {Vec3(1e-9, 1e9, 0.5), Vec3(2, 2, 2), Vec3(3, 3, 3), Vec3(M_PI, M_E, std::sqrt(2.0))}};
  lines.cell_data = {{"fibre_r", {0, 1, 0}}, {"fibre_s", {0, 0, 1}}, {"length", {1.5, 2.0 / 3.0, 0.1}}};
  return lines;
}

void write_text(const std::string& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

const CellArray* find(const Polylines& lines, const std::string& name) {
  for (const CellArray& a : lines.cell_data)
    if (a.name == name) return &a;
  return nullptr;
}

/// Reading `text` as `name` throws InputError with `code` and a message holding `where`.
void check_error(const std::string& name, const std::string& text, ErrorCode code, const std::string& where) {
  TempDir dir;
  const std::string path = dir.file(name);
  write_text(path, text);
  CAPTURE(name, text);
  try {
    read_polylines(path);
    FAIL("no exception");
  } catch (const InputError& e) {
    const std::string message = e.what();
    CAPTURE(message);
    CHECK(e.code() == code);
    CHECK(message.find(path + ": " + where) == 0);
    CHECK(message.find('\n') == std::string::npos);
  }
}

const char* const kVtp = R"(<?xml version="1.0"?>
<!-- two lines, one vertex cell before them -->
<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian">
  <PolyData>
    <Piece NumberOfPoints="4" NumberOfVerts="1" NumberOfLines="2" NumberOfStrips="0" NumberOfPolys="0">
      <PointData><DataArray type="Float32" Name="p" format="binary">AAAA</DataArray></PointData>
      <Points>
        <DataArray type="Float32" NumberOfComponents="3" format="ascii">
          0 0 0  1 0 0  2 0 0
          3 1e-1 -2.5
        </DataArray>
      </Points>
      <Verts>
        <DataArray type="Int32" Name="connectivity" format="ascii">0</DataArray>
        <DataArray type="Int32" Name="offsets" format="ascii">1</DataArray>
      </Verts>
      <Lines>
        <DataArray type="Int32" Name="connectivity" format="ascii">0 1 2 3 2</DataArray>
        <DataArray type="Int32" Name="offsets" format="ascii">3 5</DataArray>
      </Lines>
      <CellData>
        <DataArray type="Int32" Name='a &amp; b' format="ascii">7 10 11</DataArray>
        <DataArray type="Float64" Name="vec" NumberOfComponents="3" format="ascii">1 2 3 4 5 6 7 8 9</DataArray>
      </CellData>
    </Piece>
  </PolyData>
</VTKFile>
)";

}  // namespace

TEST_CASE("polylines round-trip exactly through vtk vtp obj and csv", "[geometry][io][polylines]") {
  TempDir dir;
  const Polylines lines = awkward_fibres();
  for (const std::string ext : {"vtk", "vtp", "obj", "csv", "VTP", "Csv"}) {
    CAPTURE(ext);
    const std::string path = dir.file("fibres." + ext);
    write_polylines(path, lines);
    const Polylines back = read_polylines(path);
    REQUIRE(back.lines.size() == lines.lines.size());
    for (std::size_t f = 0; f < lines.lines.size(); ++f) {
      REQUIRE(back.lines[f].size() == lines.lines[f].size());
      for (std::size_t k = 0; k < lines.lines[f].size(); ++k)
        for (int c = 0; c < 3; ++c) CHECK(back.lines[f][k][c] == lines.lines[f][k][c]);  // bit-exact values
    }
    const std::string lower = ext == "VTP" ? "vtp" : ext == "Csv" ? "csv" : ext;
    if (lower == "obj") {
      CHECK(back.cell_data.empty());
    } else if (lower == "csv") {
      REQUIRE(back.cell_data.size() == 2);  // only the lattice indices have columns
      CHECK(find(back, "fibre_r")->values == lines.cell_data[0].values);
      CHECK(find(back, "fibre_s")->values == lines.cell_data[1].values);
    } else {
      REQUIRE(back.cell_data.size() == 3);
      for (std::size_t a = 0; a < 3; ++a) {
        CHECK(back.cell_data[a].name == lines.cell_data[a].name);
        CHECK(back.cell_data[a].values == lines.cell_data[a].values);
      }
    }
  }
}

TEST_CASE("CSV has one row per point with r and s from the lattice arrays or the fibre index",
          "[geometry][io][polylines]") {
  TempDir dir;
  Polylines lines;
  lines.lines = {{Vec3(0, 0, 0), Vec3(1, 0, 0)}, {Vec3(0, 1, 0), Vec3(0.5, 1, 0), Vec3(1, 1, 0)}};
  write_polylines(dir.file("plain.csv"), lines);
  CHECK(read_text(dir.file("plain.csv")) ==
        "fibre,r,s,point,x,y,z\n0,0,0,0,0,0,0\n0,0,0,1,1,0,0\n1,1,0,0,0,1,0\n1,1,0,1,0.5,1,0\n1,1,0,2,1,1,0\n");
  lines.cell_data = {{"fibre_s", {4, 5}}, {"fibre_r", {2, 3}}};
  write_polylines(dir.file("lattice.csv"), lines);
  const std::string text = read_text(dir.file("lattice.csv"));
  CHECK(text.find("\n1,3,5,2,1,1,0\n") != std::string::npos);

  // Rows in any order: grouped by fibre (increasing number), points ordered by `point`.
  write_text(dir.file("shuffled.csv"),
             "fibre,r,s,point,x,y,z\r\n7,1,2,1,1,0,0\r\n3,0,0,5,9,9,9\r\n\r\n7,1,2,0,0,0,0\r\n3,0,0,2,8,8,8\r\n");
  const Polylines back = read_polylines(dir.file("shuffled.csv"));
  REQUIRE(back.lines.size() == 2);
  CHECK(back.lines[0] == std::vector<Vec3>{Vec3(8, 8, 8), Vec3(9, 9, 9)});
  CHECK(back.lines[1] == std::vector<Vec3>{Vec3(0, 0, 0), Vec3(1, 0, 0)});
  CHECK(find(back, "fibre_r")->values == std::vector<double>{0, 1});
  CHECK(find(back, "fibre_s")->values == std::vector<double>{0, 2});
}

TEST_CASE("VTP keeps the cell data of the lines and skips other arrays", "[geometry][io][polylines]") {
  TempDir dir;
  write_text(dir.file("a.vtp"), kVtp);
  const Polylines lines = read_polylines(dir.file("a.vtp"));
  REQUIRE(lines.lines.size() == 2);
  CHECK(lines.lines[0] == std::vector<Vec3>{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 0, 0)});
  CHECK(lines.lines[1] == std::vector<Vec3>{Vec3(3, 0.1, -2.5), Vec3(2, 0, 0)});
  REQUIRE(lines.cell_data.size() == 1);  // the 3-component array is skipped
  CHECK(lines.cell_data[0].name == "a & b");
  CHECK(lines.cell_data[0].values == std::vector<double>{10, 11});  // after the vertex cell

  // The writer escapes names the same way.
  Polylines named;
  named.lines = {{Vec3(0, 0, 0), Vec3(1, 1, 1)}};
  named.cell_data = {{"<x> & \"y\"", {2.5}}};
  write_polylines(dir.file("b.vtp"), named);
  const Polylines back = read_polylines(dir.file("b.vtp"));
  REQUIRE(back.cell_data.size() == 1);
  CHECK(back.cell_data[0].name == "<x> & \"y\"");
  CHECK(back.cell_data[0].values == std::vector<double>{2.5});
}

TEST_CASE("malformed CSV polylines give one-line errors with the line", "[geometry][io][polylines]") {
  const std::string h = "fibre,r,s,point,x,y,z\n";
  check_error("a.csv", "fibre,r,s,x,y,z\n0,0,0,0,1,2\n", ErrorCode::malformed, "line 1: expected the header");
  check_error("a.csv", h, ErrorCode::file_empty, "holds no polylines");
  check_error("a.csv", h + "0,0,0,0,1,2,3\n0,0,0,1,1,2\n", ErrorCode::malformed, "line 3: expected 7");
  check_error("a.csv", h + "0,0,0,0,1,2,3,4\n", ErrorCode::malformed, "line 2: expected 7");
  check_error("a.csv", h + "0,0,0,0,1,2,3\n0,0,0,1,1,abc,3\n", ErrorCode::bad_number, "line 3: y 'abc'");
  check_error("a.csv", h + "0,0,0,0,1,2,nan\n", ErrorCode::bad_number, "line 2: z is nan");
  check_error("a.csv", h + "0,0,0,0,1,2,1e999\n", ErrorCode::bad_number, "line 2: z is 1e999");
  check_error("a.csv", h + "x,0,0,0,1,2,3\n", ErrorCode::malformed, "line 2: fibre 'x'");
  check_error("a.csv", h + "-1,0,0,0,1,2,3\n", ErrorCode::malformed, "line 2: fibre '-1'");
  check_error("a.csv", h + "0,0,0,1.5,1,2,3\n", ErrorCode::malformed, "line 2: point '1.5'");
  check_error("a.csv", h + "0,0,0,0,1,2,3\n0,1,0,1,1,2,3\n", ErrorCode::malformed, "line 3: fibre 0 has r, s");
  check_error("a.csv", h + "0,0,0,0,1,2,3\n\n0,0,0,0,1,2,3\n", ErrorCode::malformed,
              "line 2: fibre 0 has point 0 twice");
  check_error("a.csv", "", ErrorCode::file_empty, "line 1");
}

TEST_CASE("malformed VTP polylines give one-line errors with the line", "[geometry][io][polylines]") {
  const std::string head = "<VTKFile type=\"PolyData\">\n<PolyData>\n";
  const std::string piece = "<Piece NumberOfPoints=\"2\" NumberOfLines=\"1\">\n";
  const std::string points =
      "<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">0 0 0 1 1 "
      "1</DataArray></Points>\n";
  const std::string lines =
      "<Lines><DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">0 1</DataArray>\n"
      "<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">2</DataArray></Lines>\n";
  const std::string tail = "</Piece>\n</PolyData>\n</VTKFile>\n";
  {
    TempDir dir;  // the pieces make a valid file
    write_text(dir.file("ok.vtp"), head + piece + points + lines + tail);
    CHECK(read_polylines(dir.file("ok.vtp")).lines.size() == 1);
  }
  check_error("a.vtp", "<foo/>\n", ErrorCode::unknown_format, "line 1: not a VTK XML file");
  check_error("a.vtp", "<VTKFile type=\"UnstructuredGrid\">\n</VTKFile>\n", ErrorCode::unknown_format,
              "line 1: VTK XML file of type 'UnstructuredGrid'");
  check_error("a.vtp", head + piece + points, ErrorCode::truncated, "line 5: file ends inside <Piece>");
  check_error("a.vtp",
              head + piece + "<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">0 0 0\n1 1",
              ErrorCode::truncated, "line 5: file ends inside a DataArray");
  check_error("a.vtp",
              head + piece +
                  "<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">0 0 0\n1 x "
                  "1</DataArray></Points>\n" +
                  lines + tail,
              ErrorCode::bad_number, "line 5: value 'x'");
  check_error("a.vtp",
              head + piece +
                  "<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">0 0 0 1 "
                  "1</DataArray></Points>\n" +
                  lines + tail,
              ErrorCode::malformed, "line 4: Points DataArray holds 5 values");
  check_error(
      "a.vtp",
      head + piece +
          "<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"binary\">AAAA</DataArray></Points>\n" +
          lines + tail,
      ErrorCode::unknown_format, "line 4: DataArray '' has format 'binary'");
  check_error("a.vtp",
              head + piece + points +
                  "<Lines><DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">0\n5</DataArray>\n"
                  "<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">2</DataArray></Lines>\n" +
                  tail,
              ErrorCode::index_out_of_range, "line 5: connectivity entry 1: point index 5");
  check_error("a.vtp",
              head + piece + points +
                  "<Lines><DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">0 1</DataArray>\n"
                  "<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">3</DataArray></Lines>\n" +
                  tail,
              ErrorCode::malformed, "line 6: offset 0 (3)");
  check_error("a.vtp",
              head + piece + points +
                  "<Lines><DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">0 1.5</DataArray>\n" + tail,
              ErrorCode::malformed, "line 5: value '1.5'");
  check_error("a.vtp", head + "<Piece NumberOfPoints=\"99999999999\" NumberOfLines=\"1\">\n" + points + lines + tail,
              ErrorCode::too_large, "line 3: declares 99999999999 points");
  check_error("a.vtp", head + "<Piece NumberOfPoints=\"two\">\n" + tail, ErrorCode::malformed,
              "line 3: NumberOfPoints 'two'");
  check_error("a.vtp", head + piece + points + lines + "</Points>\n" + tail, ErrorCode::malformed,
              "line 7: end tag </Points> does not close <Piece>");
  check_error("a.vtp",
              head + piece + points + lines +
                  "<CellData><DataArray type=\"Float64\" Name=\"c\" format=\"ascii\">1 2</DataArray></CellData>\n" +
                  tail,
              ErrorCode::malformed, "line 7: CellData array 'c' holds 2 values for 1 cells");
  check_error("a.vtp", head + "<Piece NumberOfPoints=\"2\" NumberOfLines=\"0\">\n" + points + tail,
              ErrorCode::file_empty, "holds no polylines");
  check_error("a.vtp", head + piece + points + tail, ErrorCode::malformed, "<Lines> needs");
  check_error("a.vtp", "<VTKFile type=\"PolyData\" x=1>", ErrorCode::malformed, "line 1: value of attribute 'x'");
  check_error("a.vtp", "<!-- open comment", ErrorCode::truncated, "line 1: file ends inside a comment");
}

TEST_CASE("polyline formats are chosen by extension", "[geometry][io][polylines]") {
  TempDir dir;
  Polylines lines;
  lines.lines = {{Vec3(0, 0, 0), Vec3(1, 0, 0)}};
  CHECK_THROWS_AS(write_polylines(dir.file("f.txt"), lines), InputError);
  CHECK_FALSE(std::filesystem::exists(dir.file("f.txt")));
  write_text(dir.file("f.xyz"), "0 0 0\n");
  try {
    read_polylines(dir.file("f.xyz"));
    FAIL("no exception");
  } catch (const InputError& e) { CHECK(e.code() == ErrorCode::unknown_format); }
  try {
    read_polylines(dir.file("missing.vtp"));
    FAIL("no exception");
  } catch (const InputError& e) { CHECK(e.code() == ErrorCode::file_missing); }
}
