#pragma once
/// \file decompose_mesh.h
/// The whole job on a raw muscle surface: the repair stage (repair/repair.h), then the
/// decomposition of the repaired mesh (fibres/decompose.h). The two stages meet through plain
/// data: the repaired TriangleMesh and the repair's JSON report.
#include "fibres/decompose.h"
#include "geometry/mesh.h"
#include "repair/repair.h"

namespace fascicle {

/// Decomposes the raw muscle `soup` (any units) into fibres: repair_mesh(soup, repair), then
/// decompose_repaired() on the repaired mesh; the report's `repair` and `seconds.repair` hold the
/// repair's report and time, and its total includes the repair. The result's report says
/// "failed" when the final check fails (the fibres are still returned for inspection; the
/// command line then writes no fibre file). Throws TopologyError (repair_failed) when the mesh
/// cannot be repaired, else as decompose_repaired().
Decomposition decompose(const PolygonSoup& soup, const Landmarks& landmarks, const DecomposeOptions& options = {},
                        const RepairOptions& repair = {});

}  // namespace fascicle
