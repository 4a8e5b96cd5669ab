"""Poses on the server (docs/serving/animation.md): a skeleton and its clips uploaded once,
then frames that name clip layers instead of carrying a palette; the server samples,
blends and turns them into the palette. The messages both clients send, checked here."""
from dataclasses import dataclass
from typing import Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

from . import _arrays
from ._requests import ENCODINGS, check_encoding
from .v1 import skinning_pb2 as pb

PATHS = {"translation": (pb.CLIP_PATH_TRANSLATION, 3), "rotation": (pb.CLIP_PATH_ROTATION, 4),
         "scale": (pb.CLIP_PATH_SCALE, 3), "weights": (pb.CLIP_PATH_WEIGHTS, 0)}
INTERPOLATIONS = {"linear": pb.CLIP_INTERPOLATION_LINEAR, "step": pb.CLIP_INTERPOLATION_STEP,
                  "cubicspline": pb.CLIP_INTERPOLATION_CUBICSPLINE}


@dataclass(frozen=True)
class PoseLayer:
    """One clip of a pose: sampled at `time` seconds (looped past its duration, or clamped),
    weighted (the layers that are not additive are normalised)."""
    clip_id: str
    time: float
    weight: float = 1.0
    additive: bool = False
    loop: bool = False


@dataclass(frozen=True)
class Pose:
    """What a character plays instead of a palette: 1..8 layers of the skeleton's clips."""
    skeleton_id: str
    layers: Sequence[PoseLayer]


# One frame of a stream: a palette float32 (J, 3, 4) (or a crowd's), or a Pose the server
# turns into the palette.
PaletteOrPose = Union[npt.NDArray[np.float32], Pose]


@dataclass(frozen=True)
class ClipTrack:
    """One glTF channel: path "translation", "rotation" (x y z w), "scale" (of joint
    `target`) or "weights" (morph weights group `target`, `width` a key); float32 times
    (K,) and values (K, width), or (K, 3, width) for "cubicspline" (in-tangent, value,
    out-tangent)."""
    path: str
    target: int
    times: npt.NDArray[np.float32]
    values: npt.NDArray[np.float32]
    interpolation: str = "linear"


def skeleton_request(parents: npt.NDArray[np.int16], rest: npt.NDArray[np.float32],
                     palette_joints: npt.NDArray[np.uint16],
                     inverse_bind: npt.NDArray[np.float32],
                     names: Optional[Sequence[str]] = None) -> pb.UploadSkeletonRequest:
    """parents (J,) int16 (-1: a root; parents before children); rest (J, 10) float32:
    translation, rotation x y z w, scale; palette_joints (P,) uint16; inverse_bind (P, 3, 4)
    float32 row-major. The server checks the values and names the field."""
    joints = len(parents)
    if np.shape(rest) != (joints, 10):
        raise ValueError(f"rest: shape {np.shape(rest)}, expected ({joints}, 10)")
    entries = len(palette_joints)
    if np.shape(inverse_bind) != (entries, 3, 4):
        raise ValueError(f"inverse_bind: shape {np.shape(inverse_bind)}, expected "
                         f"({entries}, 3, 4)")
    return pb.UploadSkeletonRequest(
        parents=_arrays.little_endian_bytes(np.asarray(parents), "i2"),
        rest=_arrays.little_endian_bytes(np.asarray(rest), "f4"), names=list(names or []),
        palette_joints=_arrays.little_endian_bytes(np.asarray(palette_joints), "u2"),
        inverse_bind=_arrays.little_endian_bytes(np.asarray(inverse_bind), "f4"))


def clip_request(skeleton_id: str, tracks: Sequence[ClipTrack], name: str = "",
                 duration: float = 0.0, max_error_mm: float = 0.0) -> pb.UploadClipRequest:
    """A clip for a stored skeleton; duration 0: its last key time. max_error_mm: the error
    the server stores it to (UploadClipRequest.max_error_mm; 0: its default, 0.01 mm; else
    0.01 to 10, checked by the server); a looser bound stores fewer bytes."""
    request = pb.UploadClipRequest(skeleton_id=skeleton_id, name=name, duration=duration,
                                   max_error_mm=max_error_mm)
    for i, t in enumerate(tracks):
        if t.path not in PATHS:
            raise ValueError(f"tracks[{i}].path: {t.path!r}, expected one of {sorted(PATHS)}")
        if t.interpolation not in INTERPOLATIONS:
            raise ValueError(f"tracks[{i}].interpolation: {t.interpolation!r}, expected one "
                             f"of {sorted(INTERPOLATIONS)}")
        values = np.asarray(t.values, dtype=np.float32)
        # A value's floats: fixed by the path, or the weights' count (values' last axis).
        width = PATHS[t.path][1] or (values.shape[-1] if values.ndim > 1 else 0)
        request.tracks.append(pb.ClipTrack(
            path=PATHS[t.path][0], interpolation=INTERPOLATIONS[t.interpolation],
            target=t.target, width=width,
            times=_arrays.little_endian_bytes(np.asarray(t.times, dtype=np.float32), "f4"),
            values=_arrays.little_endian_bytes(values, "f4")))
    return request


def check_pose(what: str, pose: Pose) -> None:
    """What the client can tell before sending: a Pose of 1..8 PoseLayer (`what` names it in
    the error); the server checks the ids, times and weights and names the field."""
    if not isinstance(pose, Pose):
        raise ValueError(f"{what}: {type(pose).__name__}, expected skinserve.Pose")
    if not 1 <= len(pose.layers) <= 8:
        raise ValueError(f"{what}.layers: {len(pose.layers)} layers, expected 1..8")
    for i, layer in enumerate(pose.layers):
        if not isinstance(layer, PoseLayer):
            raise ValueError(f"{what}.layers[{i}]: {type(layer).__name__}, expected "
                             "skinserve.PoseLayer")


def set_pose(request: pb.SkinRequest, pose: Pose) -> None:
    """`request` carries `pose` (and no palette): the server computes the palette."""
    request.ClearField("palette")
    request.pose.skeleton_id = pose.skeleton_id
    for layer in pose.layers:
        request.pose.layers.append(pb.PoseLayer(
            clip_id=layer.clip_id, time=layer.time, weight=layer.weight,
            additive=layer.additive, loop=layer.loop))


def pose_request(mesh_id: str, pose: Pose, frame: int, backend: Optional[str],
                 want_normals: bool, encoding: str) -> pb.SkinRequest:
    """One frame whose palette the server computes from `pose`."""
    check_pose("pose", pose)
    check_encoding(encoding)
    request = pb.SkinRequest(mesh_id=mesh_id, backend=backend or "", frame=frame,
                             want_normals=want_normals, encoding=ENCODINGS[encoding],
                             pack_instances=True)
    set_pose(request, pose)
    return request
