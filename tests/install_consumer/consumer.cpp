// Decomposes a capsule through the installed library: prints the fibre count and the check's
// verdict, exit 0 when the decomposition passes.
#include "fibres/decompose_mesh.h"
#include "geometry/primitives.h"

#include <cstdio>

int main() {
  using namespace fascicle;
  const PolygonSoup soup = to_soup(make_capsule(10.0, 1.5, 24));
  DecomposeOptions options;
  options.fibres = 16;
  options.resolution = 8;
  const Decomposition result = decompose(soup, Landmarks{}, options);
  std::printf("fibres %zu, status %s\n", result.fibres.lines.size(), result.report.status.c_str());
  return result.report.status == "ok" && result.fibres.lines.size() == 16 ? 0 : 1;
}
