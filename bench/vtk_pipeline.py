#!/usr/bin/python3
"""VTK's whole surface pipeline, stage by stage, for ratios with pipeline_bench.

usage: vtk_pipeline.py (--nrrd VOLUME.nrrd | --dicom DIR) [--iso 300,-500] [--threads 1]
                       [--repeat 3] [--out-dir /tmp] [--machine]
Needs Debian's python3-vtk9 (benchmark only; VTK is never a dependency of typemerge).

Stages: read (the NRRD pipeline_bench --write-nrrd wrote, with numpy as vtk_extract.py does
since Debian's vtkNrrdReader wants MPI; or a DICOM folder with vtkDICOMImageReader, whose
output is already HU, as int16), flying_edges (vtkFlyingEdges3D, no normals, gradients or
scalars, like vtk_extract.py) and write (vtkSTLWriter, binary). Per stage it prints the
median wall and CPU time (process CPU time, all threads), M cells/s, triangles and the peak
resident memory during the stage (VmHWM, reset through /proc/self/clear_refs before each
stage). --machine adds "stage NAME WALL_MS CPU_MS TRIANGLES PEAK_MIB" lines, which
pipeline_bench --vtk reads. --threads sets vtkSMPTools (the TBB backend on Debian).
"""
import argparse
import gc
import os
import statistics
import time

import vtk

from vtk_extract import read_nrrd


def peak_mib():
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    return -1


def reset_peak():
    try:
        with open("/proc/self/clear_refs", "w") as clear:
            clear.write("5")
    except OSError:
        pass


def timed(work):
    """(result, wall ms, cpu ms, peak MiB during the call)."""
    gc.collect()
    reset_peak()
    cpu = time.process_time()
    start = time.perf_counter()
    result = work()
    wall = (time.perf_counter() - start) * 1e3
    return result, wall, (time.process_time() - cpu) * 1e3, peak_mib()


def read_dicom(folder):
    """vtkDICOMImageReader applies the rescale itself: its output is already HU (int16)."""
    reader = vtk.vtkDICOMImageReader()
    reader.SetDirectoryName(folder)
    reader.Update()
    image = vtk.vtkImageData()
    image.ShallowCopy(reader.GetOutput())
    return image


def flying_edges(image, iso):
    f = vtk.vtkFlyingEdges3D()
    f.SetInputData(image)
    f.SetValue(0, iso)
    f.ComputeNormalsOff()
    f.ComputeGradientsOff()
    f.ComputeScalarsOff()
    f.Update()
    return f.GetOutput()


def write_stl(poly, path):
    writer = vtk.vtkSTLWriter()
    writer.SetInputData(poly)
    writer.SetFileTypeToBinary()
    writer.SetFileName(path)
    writer.Write()


def main():
    parser = argparse.ArgumentParser()
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--nrrd")
    source.add_argument("--dicom")
    parser.add_argument("--iso", default="300,-500")
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--out-dir", default="/tmp")
    parser.add_argument("--machine", action="store_true")
    args = parser.parse_args()
    vtk.vtkObject.GlobalWarningDisplayOff()  # the reader warns about every non-DICOM file
    vtk.vtkMultiThreader.SetGlobalMaximumNumberOfThreads(args.threads)
    vtk.vtkSMPTools.Initialize(args.threads)
    read = (lambda: read_nrrd(args.nrrd)) if args.nrrd else (lambda: read_dicom(args.dicom))
    path = os.path.join(args.out_dir, "vtk_pipeline.stl")

    for iso in [float(v) for v in args.iso.split(",")]:
        runs = {"read": [], "flying_edges": [], "write": []}
        for _ in range(args.repeat):
            image, *figures = timed(read)
            runs["read"].append((*figures, 0))
            poly, *figures = timed(lambda: flying_edges(image, iso))
            triangles = poly.GetNumberOfCells()
            runs["flying_edges"].append((*figures, triangles))
            _, *figures = timed(lambda: write_stl(poly, path))
            runs["write"].append((*figures, (os.path.getsize(path) - 84) // 50))
            del image, poly
        nx, ny, nz = read().GetDimensions()
        cells = (nx - 1) * (ny - 1) * (nz - 1)
        source_name = args.nrrd or args.dicom
        print(f"VTK {vtk.vtkVersion.GetVTKVersion()} ({vtk.vtkSMPTools.GetBackend()}, "
              f"{args.threads} thread(s)): {source_name}, {nx}x{ny}x{nz}, iso {iso:g}")
        print(f"  {'stage':14} {'wall ms':>9} {'cpu ms':>9} {'Mcells/s':>9} {'triangles':>11} "
              f"{'peak MiB':>9}")
        total = 0.0
        for name, values in runs.items():
            wall = statistics.median(v[0] for v in values)
            cpu = statistics.median(v[1] for v in values)
            peak = max(v[2] for v in values)
            triangles = values[-1][3]
            total += wall
            rate = f"{cells / wall / 1e3:9.1f}" if name != "write" else f"{'-':>9}"
            print(f"  {name:14} {wall:9.1f} {cpu:9.1f} {rate} {triangles:11d} {peak:9.1f}")
            if args.machine:
                print(f"stage {name} {wall:.3f} {cpu:.3f} {triangles} {peak:.1f}")
        print(f"  {'total':14} {total:9.1f}")


if __name__ == "__main__":
    main()
