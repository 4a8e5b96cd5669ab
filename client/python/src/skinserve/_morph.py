"""Morph targets (blend shapes): a mesh's sparse targets for upload and a frame's sparse
weights (docs/characters.md#morph-targets). A frame adds sum_t weight_t * delta_t to the rest
positions (and normals, tangents) of the vertices each active target moves, before skinning."""
import math
from typing import Any, List, Mapping, NamedTuple, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

from . import _arrays
from .v1 import skinning_pb2 as pb


class MorphTarget(NamedTuple):
    """One target, sparse: the vertices it moves (uint32 (D,), ascending) and their deltas,
    float32 (D, 3) for positions and, optionally, for normals (then every target of the mesh
    has normal deltas and the mesh has normals) and for tangents' xyz (then every target has
    tangent deltas and the mesh has tangents; w is never morphed)."""
    indices: npt.NDArray[np.uint32]
    positions: npt.NDArray[np.float32]
    normals: Optional[npt.NDArray[np.float32]] = None
    tangents: Optional[npt.NDArray[np.float32]] = None


# A frame's weights, sparse: {target index: weight}; targets left out weigh 0.
Weights = Mapping[int, float]
# A frame's weights for `skin`/`stream`: one Weights for the whole frame (every instance of
# a crowd), or a sequence of K of them, one per instance of a crowd of K.
FrameWeights = Union[Weights, Sequence[Weights]]


def check_targets(targets: Sequence[MorphTarget], vertices: int, has_normals: bool,
                  has_tangents: bool = False) -> Tuple[List[int], bool, bool]:
    """Each target's size, and whether they carry normal deltas and tangent deltas.
    ValueError naming the target and the array; the server checks the values (range,
    order)."""
    sizes: List[int] = []
    for i, target in enumerate(targets):
        if not isinstance(target, MorphTarget):
            raise ValueError(f"morph_targets[{i}]: expected a skinserve.MorphTarget, got "
                             f"{type(target).__name__}")
    with_normals = [t.normals is not None for t in targets]
    if any(with_normals) and not all(with_normals):
        raise ValueError("morph_targets: some targets have normal deltas and some not; give "
                         "every target normals or none")
    if any(with_normals) and not has_normals:
        raise ValueError("morph_targets: normal deltas, but the mesh has no normals")
    with_tangents = [t.tangents is not None for t in targets]
    if any(with_tangents) and not all(with_tangents):
        raise ValueError("morph_targets: some targets have tangent deltas and some not; give "
                         "every target tangents or none")
    if any(with_tangents) and not has_tangents:
        raise ValueError("morph_targets: tangent deltas, but the mesh has no tangents")
    for i, target in enumerate(targets):
        _arrays.check_array(f"morph_targets[{i}].indices", target.indices, np.uint32, 1)
        count = int(target.indices.shape[0])
        if count > vertices:
            raise ValueError(f"morph_targets[{i}].indices: {count} entries, more than the "
                             f"mesh's {vertices} vertices")
        for name, deltas in (("positions", target.positions), ("normals", target.normals),
                             ("tangents", target.tangents)):
            if deltas is None:
                continue
            _arrays.check_array(f"morph_targets[{i}].{name}", deltas, np.float32, 2)
            if deltas.shape != (count, 3):
                raise ValueError(f"morph_targets[{i}].{name}: shape {deltas.shape}, expected "
                                 f"({count}, 3) (one delta per index)")
        sizes.append(count)
    return sizes, any(with_normals), any(with_tangents)


def target_arrays(targets: Sequence[MorphTarget]
                  ) -> List[Tuple["pb.MeshArray", Optional[npt.NDArray[Any]], str]]:
    """The upload's morph arrays (kind, values, dtype), all targets back to back."""
    if not targets:
        return []
    indices = np.concatenate([t.indices for t in targets])
    positions = np.concatenate([t.positions.reshape(-1) for t in targets])
    normals = (np.concatenate([t.normals.reshape(-1) for t in targets if t.normals is not None])
               if targets[0].normals is not None else None)
    tangents = (np.concatenate([t.tangents.reshape(-1) for t in targets
                                if t.tangents is not None])
                if targets[0].tangents is not None else None)
    return [(pb.MESH_ARRAY_MORPH_INDICES, indices, "u4"),
            (pb.MESH_ARRAY_MORPH_POSITION_DELTAS, positions, "f4"),
            (pb.MESH_ARRAY_MORPH_NORMAL_DELTAS, normals, "f4"),
            (pb.MESH_ARRAY_MORPH_TANGENT_DELTAS, tangents, "f4")]


def _pairs(name: str, weights: Any) -> Tuple[List[int], List[float]]:
    if not isinstance(weights, Mapping):
        raise ValueError(f"{name}: expected a mapping {{target: weight}}, got "
                         f"{type(weights).__name__}")
    targets: List[int] = []
    values: List[float] = []
    for target, weight in weights.items():
        if isinstance(target, bool) or not isinstance(target, (int, np.integer)) or \
                not 0 <= int(target) < 1 << 32:
            raise ValueError(f"{name}: target {target!r}, expected an int >= 0")
        value = float(weight)
        if not math.isfinite(value):
            raise ValueError(f"{name}: weight {value} of target {int(target)} must be finite")
        targets.append(int(target))
        values.append(value)
    return targets, values


def set_weights(request: pb.SkinRequest, weights: Optional[FrameWeights],
                crowd: Optional[int]) -> None:
    """Puts a frame's weights into `request`: morph_targets/morph_weights for one Weights,
    instance_morph_weights for one per instance (their count must be the crowd's K >= 2)."""
    if weights is None:
        return
    if isinstance(weights, Mapping):
        targets, values = _pairs("morph_weights", weights)
        request.morph_targets.extend(targets)
        request.morph_weights.extend(values)
        return
    if isinstance(weights, (str, bytes)) or not isinstance(weights, Sequence):
        raise ValueError(f"morph_weights: expected a mapping {{target: weight}} or a sequence "
                         f"of them (one per instance), got {type(weights).__name__}")
    if crowd is None or crowd < 2 or len(weights) != crowd:
        raise ValueError(f"morph_weights: {len(weights)} per-instance entries, but the frame "
                         f"is {'a crowd of ' + str(crowd) if crowd else 'a single instance'}; "
                         "per-instance weights need one entry per instance of a crowd of "
                         "K >= 2")
    for k, instance in enumerate(weights):
        targets, values = _pairs(f"morph_weights[{k}]", instance)
        request.instance_morph_weights.add(targets=targets, weights=values)
