#!/usr/bin/env python3
"""Native Embree's build time for `phr bench-build`: Intel Embree's own library, called
through ctypes on the triangles phr built its trees over, so the time is Embree's commit alone
(embreex's scene build adds Python-side conversion that triples it).

    python3 bench/embree_build.py DIR --threads 1,2 --repeats 5 [--quality medium]

DIR holds `triangles.bin` (u32 count N, then N x 9 float32: v0, v1, v2), as exported by phr.
The library: $PHR_EMBREE_LIB if set, else the libembree4 inside the embreex wheel
(`python3 -m pip install embreex`), else a system libembree4 or libembree3 (Debian
`libembree-dev`). The vertex and index buffers are shared with Embree (no copy); each repeat
makes a new device-owned scene and times `rtcCommitScene` only: Embree's BVH8 with its
triangle leaves, from scratch, on a device limited to T threads.

Writes DIR/embree_build.json: the library, its version, the build quality, and per thread
count the median and all commit times in ms, and the scene bounds Embree computed (checked
against the triangles'). Exits 3 with a message when numpy or the library is missing.
"""
import ctypes
import ctypes.util
import glob
import json
import os
import statistics
import sys
import time
from pathlib import Path

RTC_GEOMETRY_TYPE_TRIANGLE = 0
RTC_BUFFER_TYPE_INDEX = 0
RTC_BUFFER_TYPE_VERTEX = 1
RTC_FORMAT_UINT3 = 0x5003
RTC_FORMAT_FLOAT3 = 0x9003
RTC_DEVICE_PROPERTY_VERSION = 0
QUALITIES = {"low": 0, "medium": 1, "high": 2}


class RTCBounds(ctypes.Structure):
    _fields_ = [(name, ctypes.c_float) for name in
                ("lower_x", "lower_y", "lower_z", "align0", "upper_x", "upper_y", "upper_z", "align1")]


def find_library():
    """The path of an Embree library, or None."""
    if os.environ.get("PHR_EMBREE_LIB"):
        return os.environ["PHR_EMBREE_LIB"]
    try:
        import embreex
        libs = Path(embreex.__file__).resolve().parent.parent / "embreex.libs"
        found = sorted(glob.glob(str(libs / "libembree4*.so*")))
        if found:
            return found[0]
    except ImportError:
        pass
    for name in ("embree4", "embree3"):
        path = ctypes.util.find_library(name)
        if path:
            return path
    return None


def load(path):
    lib = ctypes.CDLL(path)
    p = ctypes.c_void_p
    lib.rtcNewDevice.restype = p
    lib.rtcNewDevice.argtypes = [ctypes.c_char_p]
    lib.rtcGetDeviceProperty.restype = ctypes.c_ssize_t
    lib.rtcGetDeviceProperty.argtypes = [p, ctypes.c_int]
    lib.rtcGetDeviceError.restype = ctypes.c_int
    lib.rtcGetDeviceError.argtypes = [p]
    lib.rtcNewScene.restype = p
    lib.rtcNewScene.argtypes = [p]
    lib.rtcSetSceneBuildQuality.argtypes = [p, ctypes.c_int]
    lib.rtcNewGeometry.restype = p
    lib.rtcNewGeometry.argtypes = [p, ctypes.c_int]
    lib.rtcSetSharedGeometryBuffer.argtypes = [p, ctypes.c_int, ctypes.c_uint, ctypes.c_int, p,
                                               ctypes.c_size_t, ctypes.c_size_t, ctypes.c_size_t]
    lib.rtcCommitGeometry.argtypes = [p]
    lib.rtcAttachGeometry.restype = ctypes.c_uint
    lib.rtcAttachGeometry.argtypes = [p, p]
    lib.rtcReleaseGeometry.argtypes = [p]
    lib.rtcCommitScene.argtypes = [p]
    lib.rtcGetSceneBounds.argtypes = [p, ctypes.POINTER(RTCBounds)]
    lib.rtcReleaseScene.argtypes = [p]
    lib.rtcReleaseDevice.argtypes = [p]
    return lib


def commit_times(lib, vertices, indices, threads, repeats, quality):
    """Median-ready list of commit times (ms) and the last scene's bounds."""
    device = lib.rtcNewDevice(f"threads={threads}".encode())
    if not device:
        raise RuntimeError("rtcNewDevice failed")
    times, bounds = [], RTCBounds()
    try:
        for _ in range(repeats):
            scene = lib.rtcNewScene(device)
            lib.rtcSetSceneBuildQuality(scene, quality)
            geometry = lib.rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE)
            lib.rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                           vertices.ctypes.data, 0, 12, len(vertices) - 1)
            lib.rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                           indices.ctypes.data, 0, 12, len(indices))
            lib.rtcCommitGeometry(geometry)
            lib.rtcAttachGeometry(scene, geometry)
            lib.rtcReleaseGeometry(geometry)
            start = time.perf_counter()
            lib.rtcCommitScene(scene)
            times.append((time.perf_counter() - start) * 1e3)
            error = lib.rtcGetDeviceError(device)
            if error != 0:
                raise RuntimeError(f"Embree error {error} during the build")
            lib.rtcGetSceneBounds(scene, ctypes.byref(bounds))
            lib.rtcReleaseScene(scene)
    finally:
        lib.rtcReleaseDevice(device)
    return times, bounds


def main():
    import argparse
    ap = argparse.ArgumentParser(description="native Embree build time")
    ap.add_argument("folder")
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--quality", choices=sorted(QUALITIES), default="medium")
    args = ap.parse_args()
    try:
        import numpy as np
    except ImportError:
        print("numpy is not installed (python3 -m pip install numpy)", file=sys.stderr)
        sys.exit(3)
    path = find_library()
    if path is None:
        print("no Embree library: python3 -m pip install embreex (its wheel ships libembree4), "
              "apt-get install libembree-dev, or set PHR_EMBREE_LIB", file=sys.stderr)
        sys.exit(3)
    lib = load(path)
    folder = Path(args.folder)
    data = (folder / "triangles.bin").read_bytes()
    count = int(np.frombuffer(data[:4], dtype="<u4")[0])
    tris = np.frombuffer(data[4:4 + count * 36], dtype="<f4").reshape(count * 3, 3)
    # One spare vertex: Embree reads vertices with 16-byte loads past the last one.
    vertices = np.zeros((count * 3 + 1, 3), dtype=np.float32)
    vertices[:-1] = tris
    indices = np.arange(count * 3, dtype=np.uint32).reshape(count, 3)
    device = lib.rtcNewDevice(b"")
    version = lib.rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_VERSION)
    lib.rtcReleaseDevice(device)
    result = {
        "peer": "embree (native, ctypes)",
        "library": path,
        "version": f"{version // 10000}.{version // 100 % 100}.{version % 100}",
        "quality": args.quality,
        "triangles": count,
        "builds": {},
    }
    lo, hi = tris.min(axis=0), tris.max(axis=0)
    for threads in [int(t) for t in args.threads.split(",")]:
        times, b = commit_times(lib, vertices, indices, threads, max(args.repeats, 1), QUALITIES[args.quality])
        got = np.array([b.lower_x, b.lower_y, b.lower_z, b.upper_x, b.upper_y, b.upper_z])
        if count and not np.allclose(got, np.concatenate([lo, hi]), rtol=1e-5, atol=1e-6):
            raise RuntimeError(f"Embree's scene bounds {got} differ from the triangles' {lo} {hi}")
        result["builds"][str(threads)] = {"median_ms": statistics.median(times), "times_ms": times}
    (folder / "embree_build.json").write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
