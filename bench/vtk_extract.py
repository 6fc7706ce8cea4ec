#!/usr/bin/python3
"""VTK's extractors on the same NRRD volume, for a side-by-side ratio with extract_bench.

usage: vtk_extract.py VOLUME.nrrd [--iso 300,-500] [--repeat 5]
Needs Debian's python3-vtk9 (benchmark only; VTK is never a dependency of typemerge).
Prints, per iso and filter: median ms, M cells/s, triangles, and the defects of the output
(boundary edges, non-manifold edges, zero-area triangles), measured with VTK's own filters.
"""
import argparse
import statistics
import time

import numpy as np
import vtk
from vtk.util import numpy_support


def defects(poly):
    """Boundary edges, non-manifold edges and zero-area triangles, counted with numpy from the
    connectivity (vtkFeatureEdges aborts with bad_alloc on a 2 M-triangle surface here)."""
    polys = poly.GetPolys()
    connectivity = numpy_support.vtk_to_numpy(polys.GetConnectivityArray()).reshape(-1, 3)
    points = numpy_support.vtk_to_numpy(poly.GetPoints().GetData()).astype(np.float64)
    edges = np.sort(np.concatenate([connectivity[:, [0, 1]], connectivity[:, [1, 2]],
                                    connectivity[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    a, b, c = (points[connectivity[:, i]] for i in range(3))
    area = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    return int((counts == 1).sum()), int((counts > 2).sum()), int((area == 0).sum())


def read_nrrd(path):
    """The raw float/int16 NRRD that typemerge writes (Debian's vtkNrrdReader wants MPI)."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"\n\n")
    fields = {}
    for line in data[:end].decode().splitlines()[1:]:
        if ":" in line and not line.startswith("#"):
            key, value = line.split(":", 1)
            fields[key.strip()] = value.strip()
    sizes = [int(v) for v in fields["sizes"].split()]
    dtype = {"float": np.float32, "int16": np.int16}[fields["type"]]
    samples = np.frombuffer(data[end + 2:], dtype=dtype, count=sizes[0] * sizes[1] * sizes[2])
    image = vtk.vtkImageData()
    image.SetDimensions(*sizes)
    image.GetPointData().SetScalars(numpy_support.numpy_to_vtk(samples, deep=True))
    return image


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("volume")
    parser.add_argument("--iso", default="300,-500")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--no-defects", action="store_true")
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    vtk.vtkMultiThreader.SetGlobalMaximumNumberOfThreads(1)
    vtk.vtkSMPTools.Initialize(args.threads)
    image = read_nrrd(args.volume)
    nx, ny, nz = image.GetDimensions()
    cells = (nx - 1) * (ny - 1) * (nz - 1)
    print(f"volume: {args.volume}, {nx}x{ny}x{nz} ({cells / 1e6:.1f} M cells)")
    print(f"{'iso':8} {'filter':16} {'ms':>10} {'Mcells/s':>10} {'triangles':>11} "
          f"{'boundary':>9} {'nonmanif':>9} {'zeroarea':>9}")
    for iso in [float(v) for v in args.iso.split(",")]:
        for name, make in (("flying_edges", vtk.vtkFlyingEdges3D),
                           ("marching_cubes", vtk.vtkMarchingCubes)):
            times = []
            for _ in range(args.repeat):
                f = make()
                f.SetInputData(image)
                f.SetValue(0, iso)
                f.ComputeNormalsOff()
                f.ComputeGradientsOff()
                f.ComputeScalarsOff()
                start = time.perf_counter()
                f.Update()
                times.append((time.perf_counter() - start) * 1e3)
            poly = f.GetOutput()
            ms = statistics.median(times)
            b, n, z = (-1, -1, -1) if args.no_defects else defects(poly)
            print(f"{iso:<8g} {name:16} {ms:10.1f} {cells / ms / 1e3:10.1f} "
                  f"{poly.GetNumberOfCells():11d} {b:9d} {n:9d} {z:9d}")


if __name__ == "__main__":
    main()
