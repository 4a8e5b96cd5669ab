"""Decoding of a response part's vertex arrays to float32, per the proto's Encoding:
float32 as is, float16 widened, snorm16 positions mapped back into the part's Bounds
(x' = c + q * h / 32767 with c = (min + max) / 2, h = (max - min) / 2) and snorm16
normals as q / 32767."""
from typing import Any, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

FLOAT32, FLOAT16, SNORM16 = 0, 1, 2  # skinserve.v1.Encoding values


def decode_values(data: Union[bytes, memoryview], encoding: int, count: int,
                  bounds: Optional[Sequence[float]] = None,
                  normals: bool = False, width: int = 3) -> npt.NDArray[np.float32]:
    """`count` xyz triples from `data` as a (count, 3) float32 array; width=4: tangents,
    x y z w decoded as normals into (count, 4).

    bounds: (min_x, min_y, min_z, max_x, max_y, max_z), needed for snorm16 positions.
    """
    values: npt.NDArray[Any]
    if encoding == FLOAT32:
        values = np.frombuffer(data, dtype="<f4")
    elif encoding == FLOAT16:
        values = np.frombuffer(data, dtype="<f2")
    elif encoding == SNORM16:
        values = np.frombuffer(data, dtype="<i2")
    else:
        raise ValueError(f"unknown encoding {encoding}")
    if values.size != width * count:
        raise ValueError(f"response part holds {values.size} values, expected {width * count}")
    values = values.reshape(count, width)
    if encoding != SNORM16:
        return values.astype(np.float32)
    q = values.astype(np.float64)
    if normals:
        return (q / 32767.0).astype(np.float32)
    if bounds is None:
        raise ValueError("snorm16 positions without bounds")
    lo = np.asarray(bounds[:3], dtype=np.float64)
    hi = np.asarray(bounds[3:], dtype=np.float64)
    c, h = (lo + hi) / 2, (hi - lo) / 2
    return (c + q * h / 32767.0).astype(np.float32)
