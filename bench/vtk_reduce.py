#!/usr/bin/python3
"""VTK's usual reduction routes on the same volume, for reduction_bench: flying edges and
vtkCleanPolyData, then vtkQuadricDecimation, and vtkDecimatePro with the topology preserved,
to given counts.

usage: vtk_reduce.py VOLUME.nrrd OUTDIR --iso 300 --targets 210000,84000
Writes OUTDIR/fe.stl (flying edges, index space) and OUTDIR/{quadric,pro}-N.stl; prints one
line per surface: name, seconds (extraction + reduction, one thread), triangles.
Needs Debian's python3-vtk9 (benchmark only; VTK is never a dependency of typemerge).
"""
import argparse
import os
import time

import vtk

from vtk_extract import read_nrrd


def write(poly, path):
    writer = vtk.vtkSTLWriter()
    writer.SetFileTypeToBinary()
    writer.SetInputData(poly)
    writer.SetFileName(path)
    writer.Write()


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("volume")
    parser.add_argument("out")
    parser.add_argument("--iso", type=float, required=True)
    parser.add_argument("--targets", required=True)
    args = parser.parse_args()
    vtk.vtkMultiThreader.SetGlobalMaximumNumberOfThreads(1)
    vtk.vtkSMPTools.Initialize(1)
    image = read_nrrd(args.volume)

    def flying_edges():
        fe = vtk.vtkFlyingEdges3D()
        fe.SetInputData(image)
        fe.SetValue(0, args.iso)
        fe.ComputeNormalsOff()
        fe.ComputeGradientsOff()
        fe.ComputeScalarsOff()
        fe.Update()
        return fe.GetOutput()

    start = time.perf_counter()
    surface = flying_edges()
    fe_seconds = time.perf_counter() - start
    write(surface, os.path.join(args.out, "fe.stl"))
    print(f"fe {fe_seconds:.3f} {surface.GetNumberOfPolys()}", flush=True)
    count = surface.GetNumberOfPolys()
    for target in (int(t) for t in args.targets.split(",")):
        reduction = max(0.0, min(1.0, 1.0 - target / count))
        for name, make in (("quadric", vtk.vtkQuadricDecimation), ("pro", vtk.vtkDecimatePro)):
            start = time.perf_counter()
            # Flying edges repeats some points (414,685 for 409,485 distinct on the abdomen at
            # 300 HU); vtkQuadricDecimation stops almost at once on such a surface (825,490 of
            # 826,202 triangles left for a 75 % reduction), so the points are merged first.
            clean = vtk.vtkCleanPolyData()
            clean.SetInputData(flying_edges())
            clean.Update()
            source = clean.GetOutput()
            decimate = make()
            decimate.SetInputData(source)
            decimate.SetTargetReduction(reduction)
            if name == "pro":
                decimate.PreserveTopologyOn()
                decimate.SplittingOff()
                decimate.BoundaryVertexDeletionOff()
            decimate.Update()
            seconds = time.perf_counter() - start
            out = decimate.GetOutput()
            write(out, os.path.join(args.out, f"{name}-{target}.stl"))
            print(f"{name}-{target} {seconds:.3f} {out.GetNumberOfPolys()}", flush=True)


if __name__ == "__main__":
    main()
