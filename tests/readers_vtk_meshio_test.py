#!/usr/bin/env python3
"""Every fibre and mesh output of fascicle loads in the readers its users have: VTK's default
readers (vtkPolyDataReader and vtkDataSetReader, as ParaView and 3D Slicer use them, and the
XML readers) and meshio, with every array the file carries.

Usage: readers_vtk_meshio_test.py FASCICLE_PROGRAM
Exit 0 when every check passes, 1 on a failure, 77 (CTest's skip code) when python3-vtk9 or
python3-meshio is not installed.
"""
import os
import subprocess
import sys
import tempfile

try:
    import numpy
    import vtk
    import meshio
except ImportError as error:
    print("SKIPPED: the readers are not installed (python3-vtk9, python3-meshio): %s" % error)
    sys.exit(77)

program = sys.argv[1]
failures = []


def check(condition, what):
    if not condition:
        failures.append(what)
        print("FAILED: " + what)


def run(*args):
    subprocess.run([program, "-q", *args], check=True)


with tempfile.TemporaryDirectory() as folder:
    sample = os.path.join(folder, "sample.off")
    run("sample", "-o", sample, "--clean")
    repaired = os.path.join(folder, "muscle.off")
    fibres = {}
    for ext in ("vtk", "vtp", "vtu", "obj", "csv"):
        fibres[ext] = os.path.join(folder, "fibres." + ext)
    fe_mesh = os.path.join(folder, "muscle_fe.vtu")
    run("decompose", sample, "-o", fibres["vtk"], "--fibres", "36", "--resolution", "9", "--write-repaired", repaired,
        "--fe-mesh", fe_mesh, "--fe-cells", "3000")
    for ext in ("vtp", "vtu", "obj", "csv"):
        run("convert", fibres["vtk"], "-o", fibres[ext])
    lines, points = 36, 36 * 9

    def lattice_arrays(data, where):
        cells = data.GetCellData()
        for name in ("fibre_r", "fibre_s"):
            array = cells.GetArray(name)
            check(array is not None, "%s: cell array %s is there" % (where, name))
            if array is None:
                continue
            check(array.GetNumberOfTuples() == lines, "%s: %s has one value per fibre" % (where, name))
            check(array.GetDataType() in (vtk.VTK_INT, vtk.VTK_LONG, vtk.VTK_ID_TYPE, vtk.VTK_LONG_LONG),
                  "%s: %s holds integers (VTK type %d)" % (where, name, array.GetDataType()))
            values = sorted(set(int(array.GetValue(i)) for i in range(array.GetNumberOfTuples())))
            check(values == list(range(6)), "%s: %s takes the lattice indices 0..5 (%s)" % (where, name, values))

    # Legacy .vtk with both default readers.
    for reader_class in (vtk.vtkPolyDataReader, vtk.vtkDataSetReader):
        reader = reader_class()
        reader.SetFileName(fibres["vtk"])
        reader.Update()
        data = reader.GetOutput()
        where = "%s on fibres.vtk" % reader_class.__name__
        check(data.GetNumberOfPoints() == points, "%s: %d points" % (where, points))
        check(data.GetNumberOfCells() == lines, "%s: %d lines" % (where, lines))
        lattice_arrays(data, where)

    # XML files with their readers.
    for ext, reader_class in (("vtp", vtk.vtkXMLPolyDataReader), ("vtu", vtk.vtkXMLUnstructuredGridReader)):
        reader = reader_class()
        reader.SetFileName(fibres[ext])
        reader.Update()
        data = reader.GetOutput()
        where = "%s on fibres.%s" % (reader_class.__name__, ext)
        check(data.GetNumberOfPoints() == points, "%s: %d points" % (where, points))
        if ext == "vtu":
            # One line cell per fibre segment (meshio reads line cells, not poly-lines).
            cells = lines * 8
            check(data.GetNumberOfCells() == cells, "%s: %d segments" % (where, cells))
            check(all(data.GetCellType(i) == vtk.VTK_LINE for i in range(cells)), "%s: every cell a line" % where)
            fibre = data.GetCellData().GetArray("fibre")
            check(fibre is not None and sorted(set(int(fibre.GetValue(i)) for i in range(cells))) == list(range(lines)),
                  "%s: the fibre array numbers the %d fibres" % (where, lines))
            continue
        check(data.GetNumberOfCells() == lines, "%s: %d cells" % (where, lines))
        lattice_arrays(data, where)

    # meshio reads the .vtu fibres (line cells and their arrays) and the meshes.
    mesh = meshio.read(fibres["vtu"])
    check(len(mesh.points) == points, "meshio on fibres.vtu: %d points" % points)
    cells = sum(len(block.data) for block in mesh.cells if block.type == "line")
    check(cells == lines * 8, "meshio on fibres.vtu: %d segments (%d)" % (lines * 8, cells))
    for name in ("fibre_r", "fibre_s"):
        check(name in mesh.cell_data, "meshio on fibres.vtu: cell data %s" % name)
        if name in mesh.cell_data:
            values = numpy.concatenate(mesh.cell_data[name])
            check(numpy.issubdtype(values.dtype, numpy.integer), "meshio on fibres.vtu: %s holds integers" % name)
            check(sorted(set(values.tolist())) == list(range(6)), "meshio on fibres.vtu: %s is 0..5" % name)

    # Fibres read back by fascicle from every format keep their lattice arrays.
    for ext in ("vtp", "vtu", "csv"):
        out = os.path.join(folder, "back.vtk")
        run("convert", fibres[ext], "-o", out)
        reader = vtk.vtkPolyDataReader()
        reader.SetFileName(out)
        reader.Update()
        lattice_arrays(reader.GetOutput(), "fibres.%s converted back to .vtk" % ext)

    # Meshes: every format fascicle writes, with meshio and, for .vtk, VTK's generic reader.
    for ext in ("off", "obj", "stl", "ply", "vtk"):
        path = os.path.join(folder, "muscle." + ext)
        if path != repaired:
            run("convert", repaired, "-o", path)
        if ext == "vtk":
            continue  # meshio reads legacy VTK unstructured grids only; VTK reads this one below
        surface = meshio.read(path)
        triangles = sum(len(block.data) for block in surface.cells if block.type == "triangle")
        check(triangles > 0 and len(surface.points) > 0, "meshio on muscle.%s: %d triangles" % (ext, triangles))
    reader = vtk.vtkDataSetReader()
    reader.SetFileName(os.path.join(folder, "muscle.vtk"))
    reader.Update()
    check(reader.GetOutput().GetNumberOfCells() > 0, "vtkDataSetReader on muscle.vtk: triangles")

    # The finite-element mesh: tetrahedra with a unit fibre direction per cell, in VTK and meshio.
    reader = vtk.vtkXMLUnstructuredGridReader()
    reader.SetFileName(fe_mesh)
    reader.Update()
    grid = reader.GetOutput()
    tets = grid.GetNumberOfCells()
    check(tets > 1000, "vtkXMLUnstructuredGridReader on muscle_fe.vtu: %d tetrahedra" % tets)
    check(all(grid.GetCellType(i) == vtk.VTK_TETRA for i in range(tets)), "muscle_fe.vtu: every cell a tetrahedron")
    direction = grid.GetCellData().GetArray("fibre_direction")
    check(direction is not None and direction.GetNumberOfComponents() == 3 and direction.GetNumberOfTuples() == tets,
          "muscle_fe.vtu: fibre_direction has three components per cell (VTK)")
    if direction is not None:
        norms = [numpy.linalg.norm(direction.GetTuple3(i)) for i in range(direction.GetNumberOfTuples())]
        check(max(abs(n - 1.0) for n in norms) < 1e-9, "muscle_fe.vtu: every fibre direction is a unit vector")
    volume = vtk.vtkMeshQuality()
    volume.SetInputData(grid)
    volume.SetTetQualityMeasureToVolume()
    volume.Update()
    quality = volume.GetOutput().GetCellData().GetArray("Quality")
    check(quality is not None and min(quality.GetValue(i) for i in range(tets)) > 0.0,
          "muscle_fe.vtu: every tetrahedron has a positive volume")
    fe = meshio.read(fe_mesh)
    blocks = [block for block in fe.cells if block.type == "tetra"]
    check(sum(len(block.data) for block in blocks) == tets, "meshio on muscle_fe.vtu: %d tetrahedra" % tets)
    check("fibre_direction" in fe.cell_data, "meshio on muscle_fe.vtu: cell data fibre_direction")
    if "fibre_direction" in fe.cell_data:
        values = numpy.concatenate(fe.cell_data["fibre_direction"])
        check(values.shape == (tets, 3), "meshio on muscle_fe.vtu: fibre_direction is %d x 3" % tets)

if failures:
    print("%d check(s) failed" % len(failures))
    sys.exit(1)
print("all reader checks passed")
