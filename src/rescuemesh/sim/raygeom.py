"""MuJoCo's ray-geom intersection, `mju_rayGeom`, callable from numba-compiled code.

Owns: finding libmujoco's symbol for numba and the function's C signature. Must not know which
geoms or rays are cast (lidar.py decides).

`mju_rayGeom(pos, mat, size, pnt, vec, geomtype, normal)` (mujoco.h, "Ray casting") is the test
mj_multiRay makes for each geom it does not rule out, so a ray cast on the geoms that can hit it
gives mj_multiRay's distance to the bit. Numba calls it by name: the library is loaded into LLVM's
symbol table (llvmlite's `load_library_permanently`) before any function using `ray_geom` is
compiled or loaded from numba's cache. Pointers are passed as addresses (`arr.ctypes.data`; the
x86-64 and AArch64 C ABIs pass a pointer as a 64-bit integer), so `normal` is 0 (NULL: no normal).
"""

from __future__ import annotations

from pathlib import Path

import llvmlite.binding as llvm
import mujoco
from numba import types


def _library() -> str:
    found = sorted(Path(mujoco.__file__).parent.glob("libmujoco.*"))
    if not found:
        raise ImportError(f"no libmujoco library next to {mujoco.__file__}")
    return str(found[0])


llvm.load_library_permanently(_library())

#: float64 ray_geom(pos, mat, size, pnt, vec: addresses of float64[3], [9], [3], [3], [3]; geomtype: int32;
#: normal: address or 0): the distance along vec to the geom's surface, or -1 for no intersection.
ray_geom = types.ExternalFunction(
    "mju_rayGeom",
    types.float64(types.uintp, types.uintp, types.uintp, types.uintp, types.uintp, types.intc, types.uintp),
)
