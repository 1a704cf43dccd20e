// Muscle architecture (fibres/architecture.h) on shapes whose answer is known: a box with straight
// axial fibres, and one with fibres at a known angle to the line of action.
#include "fibres/architecture.h"
#include "geometry/errors.h"
#include "geometry/primitives.h"
#include "tests/test_common.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>

using namespace fascicle;

namespace {

constexpr double kPi = 3.14159265358979323846;

// The box [0, a] x [-b/2, b/2] x [-c/2, c/2] (mesh units: millimetres).
TriangleMesh box(double a, double b, double c) {
  TriangleMesh mesh = make_cube(1.0, 2);
  for (Vec3& p : mesh.positions) p = Vec3((p.x() + 0.5) * a, p.y() * b, p.z() * c);
  return mesh;
}

AttachmentArea area_at(const std::vector<Vec3>& points) {
  AttachmentArea area;
  for (const Vec3& p : points) {
    SurfacePoint s;
    s.position = p;
    area.points.push_back(s);
  }
  return area;
}

// Areas on the end faces x = 0 and x = a, centred on the x axis.
Attachments end_areas(double a, double b) {
  Attachments areas;
  areas.origin = area_at({Vec3(0, -b / 4, 0), Vec3(0, b / 4, 0)});
  areas.insertion = area_at({Vec3(a, -b / 4, 0), Vec3(a, b / 4, 0)});
  return areas;
}

}  // namespace

TEST_CASE("architecture of straight axial fibres in a box", "[fibres][architecture]") {
  const double a = 100.0, b = 20.0, c = 20.0;
  Polylines fibres;
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 4; ++i) {
      const double y = -7.5 + 5.0 * i, z = -7.5 + 5.0 * j;
      fibres.lines.push_back({Vec3(0, y, z), Vec3(50, y, z), Vec3(a, y, z)});
    }
  const Architecture arch = measure_architecture(fibres, box(a, b, c), end_areas(a, b));
  CHECK(arch.fibres == 16);
  CHECK(arch.line_of_action.x() == Approx(1.0));
  CHECK(arch.volume_m3 == Approx(a * b * c * 1e-9));
  CHECK(arch.muscle_length_m == Approx(0.1));
  CHECK(arch.fibre_length_m.mean == Approx(0.1));
  CHECK(arch.fibre_length_m.sd == Approx(0.0).margin(1e-12));
  CHECK(arch.pennation_deg.max == Approx(0.0).margin(1e-6));
  CHECK(arch.fibre_to_muscle_length == Approx(1.0));
  // PCSA = V / L: the cross-section, 400 mm^2; force at 61 N/cm^2 = 244 N.
  CHECK(arch.pcsa_m2 == Approx(b * c * 1e-6));
  CHECK(arch.max_isometric_force_n == Approx(244.0));
  // Metres as the mesh unit: the same muscle 1000 times larger in metres.
  ArchitectureOptions metres;
  metres.metres_per_unit = 1.0;
  CHECK(measure_architecture(fibres, box(a, b, c), end_areas(a, b), metres).pcsa_m2 == Approx(b * c));
}

TEST_CASE("architecture of fibres at a known pennation angle", "[fibres][architecture]") {
  const double a = 100.0, b = 200.0, c = 20.0, angle = 30.0;
  const double rise = a * std::tan(angle * kPi / 180.0);
  Polylines fibres;
  for (int i = 0; i < 10; ++i) {
    const double y = -90.0 + 10.0 * i;
    fibres.lines.push_back({Vec3(0, y, 0), Vec3(a / 2, y + rise / 2, 0), Vec3(a, y + rise, 0)});
  }
  const Architecture arch = measure_architecture(fibres, box(a, b, c), end_areas(a, b));
  CHECK(arch.pennation_deg.mean == Approx(angle));
  CHECK(arch.pennation_deg.sd == Approx(0.0).margin(1e-9));
  const double length = a / std::cos(angle * kPi / 180.0);
  CHECK(arch.fibre_length_m.mean == Approx(length * 1e-3));
  // PCSA = V cos(theta) / L_f.
  CHECK(arch.pcsa_m2 == Approx(a * b * c * std::cos(angle * kPi / 180.0) / length * 1e-6));
  // Reversed fibres (insertion to origin) have the same acute angle.
  Polylines reversed = fibres;
  for (auto& line : reversed.lines) std::reverse(line.begin(), line.end());
  CHECK(measure_architecture(reversed, box(a, b, c), end_areas(a, b)).pennation_deg.mean == Approx(angle));
}

TEST_CASE("architecture outputs and refusals", "[fibres][architecture]") {
  test::TempDir dir;
  Polylines fibres;
  fibres.lines.push_back({Vec3(0, 0, 0), Vec3(100, 0, 0)});
  const Architecture arch = measure_architecture(fibres, box(100, 20, 20), end_areas(100, 20));
  write_architecture(dir.file("a.json"), arch);
  std::ifstream in(dir.file("a.json"));
  const nlohmann::json j = nlohmann::json::parse(in);
  CHECK(j.at("pcsa_cm2").get<double>() == Approx(4.0));
  CHECK(j.at("fibre_length_m").at("mean").get<double>() == Approx(0.1));
  write_architecture(dir.file("a.csv"), arch);
  const std::string csv = test::read_text(dir.file("a.csv"));
  CHECK(csv.rfind(Architecture::csv_header() + "\n1,", 0) == 0);
  CHECK_THROWS_AS(write_architecture(dir.file("a.txt"), arch), InputError);
  CHECK_THROWS_AS(measure_architecture(Polylines{}, box(100, 20, 20), end_areas(100, 20)), InputError);
  ArchitectureOptions bad;
  bad.specific_tension = 0.0;
  CHECK_THROWS_AS(measure_architecture(fibres, box(100, 20, 20), end_areas(100, 20), bad), OptionError);
}
