"""Checks of the caller's arrays, before anything is sent: a ValueError names the array,
what it is and what it must be. No silent conversion: a float64 array is refused rather
than rounded behind the caller's back."""
from typing import Any, Optional

import numpy as np
import numpy.typing as npt

MAX_INFLUENCES = 8


def _check(name: str, array: Any, dtype: Any, ndim: int) -> None:
    if not isinstance(array, np.ndarray):
        raise ValueError(f"{name}: expected a numpy.ndarray of {np.dtype(dtype).name}, "
                         f"got {type(array).__name__}")
    if array.dtype != np.dtype(dtype):
        raise ValueError(f"{name}: dtype {array.dtype.name}, expected {np.dtype(dtype).name} "
                         f"(convert with {name}.astype(numpy.{np.dtype(dtype).name}))")
    if array.ndim != ndim:
        raise ValueError(f"{name}: shape {array.shape}, expected {ndim} dimensions")


def check_array(name: str, array: Any, dtype: Any, ndim: int) -> None:
    """ValueError naming `name` unless `array` is an ndarray of `dtype` with `ndim` axes."""
    _check(name, array, dtype, ndim)


def check_mesh(positions: Any, joints: Any, weights: Any, normals: Any) -> None:
    _check("positions", positions, np.float32, 2)
    if positions.shape[1] != 3 or positions.shape[0] == 0:
        raise ValueError(f"positions: shape {positions.shape}, expected (V, 3) with V >= 1")
    vertices = positions.shape[0]
    _check("joints", joints, np.uint16, 2)
    if joints.shape[0] != vertices or not 1 <= joints.shape[1] <= MAX_INFLUENCES:
        raise ValueError(f"joints: shape {joints.shape}, expected ({vertices}, B) with "
                         f"1 <= B <= {MAX_INFLUENCES} (one row per vertex of positions)")
    _check("weights", weights, np.float32, 2)
    if weights.shape != joints.shape:
        raise ValueError(f"weights: shape {weights.shape}, expected {joints.shape} "
                         "(the shape of joints)")
    if normals is not None:
        _check("normals", normals, np.float32, 2)
        if normals.shape != positions.shape:
            raise ValueError(f"normals: shape {normals.shape}, expected {positions.shape} "
                             "(the shape of positions)")


def check_tangents(tangents: Any, vertices: int, has_normals: bool) -> None:
    """glTF TANGENT: float32 (V, 4), xyz a unit vector, w +1 or -1 (the server checks the
    values); tangents need normals."""
    _check("tangents", tangents, np.float32, 2)
    if tangents.shape != (vertices, 4):
        raise ValueError(f"tangents: shape {tangents.shape}, expected ({vertices}, 4) "
                         "(x y z w per vertex of positions)")
    if not has_normals:
        raise ValueError("tangents: given without normals; tangents need normals (as in glTF)")


def check_palette(name: str, palette: Any, joint_count: Optional[int] = None) -> Optional[int]:
    """A (J, 3, 4) or (J, 12) float32 palette: J row-major 3x4 affine matrices; or a crowd
    of K >= 1 instances of the mesh, (K, J, 3, 4) or (K, J, 12): one palette per instance.
    Returns K for a crowd, None for a single palette."""
    if not isinstance(palette, np.ndarray):
        raise ValueError(f"{name}: expected a numpy.ndarray of float32, "
                         f"got {type(palette).__name__}")
    if palette.dtype != np.float32:
        raise ValueError(f"{name}: dtype {palette.dtype.name}, expected float32 "
                         f"(convert with {name}.astype(numpy.float32))")
    shape = palette.shape
    single = (len(shape) == 3 and shape[1:] == (3, 4)) or (len(shape) == 2 and shape[1] == 12)
    crowd = (len(shape) == 4 and shape[2:] == (3, 4)) or (len(shape) == 3 and shape[2] == 12)
    if not (single or crowd):
        raise ValueError(f"{name}: shape {shape}, expected (J, 3, 4) or (J, 12), or a crowd "
                         "(K, J, 3, 4) or (K, J, 12)")
    if crowd and shape[0] == 0:
        raise ValueError(f"{name}: shape {shape}, a crowd of 0 instances (K >= 1)")
    joints = int(shape[1] if crowd else shape[0])
    if joints == 0:
        raise ValueError(f"{name}: shape {shape}, 0 matrices")
    if joint_count is not None and joints != joint_count:
        raise ValueError(f"{name}: {joints} matrices, the mesh has {joint_count} joints")
    return int(shape[0]) if crowd else None


def little_endian_bytes(array: npt.NDArray[Any], dtype: str) -> bytes:
    return np.ascontiguousarray(array, dtype=np.dtype(dtype).newbyteorder("<")).tobytes()
