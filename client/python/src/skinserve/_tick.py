"""Ticks (SkinRequest.characters, issue 41): many characters skinned by one request, for
both clients. A Character says what one character asks (as skin's arguments do); a tick's
answer is one CharacterResult per character, in order, a bad character failing alone."""
import dataclasses
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

import grpc
import numpy as np
import numpy.typing as npt

from . import _arrays, _pose, _requests, _shared_memory
from ._errors import SkinserveError, status_code
from ._frame import Answer, FloatArray, Frame
from ._morph import FrameWeights
from ._pose import Pose
from ._shared_memory import SharedMemoryRegion
from .v1 import skinning_pb2 as pb


@dataclasses.dataclass
class Character:
    """One character of a tick: its mesh, its palette (float32 (J, 3, 4), or a crowd's
    (K, J, 3, 4)) or instead its pose (a skinserve.Pose: the server samples and blends the
    clips and computes the palette; one instance), and what it asks of the server, as
    Client.skin's arguments: backend, want_normals, want_tangents, encoding, morph_weights,
    and region/offset (its own range of a registered SharedMemoryRegion)."""
    mesh_id: str
    palette: Optional[npt.NDArray[np.float32]] = None
    backend: Optional[str] = None
    want_normals: bool = False
    encoding: str = "float32"
    region: Optional[SharedMemoryRegion] = None
    offset: int = 0
    morph_weights: Optional[FrameWeights] = None
    want_tangents: bool = False
    pose: Optional[Pose] = None


@dataclasses.dataclass
class CharacterResult:
    """A tick's answer for one character: `error` (a SkinserveError naming the character and
    the field) when it failed, else its arrays as Client.skin answers them: `answer` is
    positions, or (positions, normals), or (positions, normals, tangents), and each is also
    an attribute ((V, 3) arrays, (K, V, 3) for a crowd; views of the region for a character
    written into one). `timing`: the server's queued_ns, compute_ns and encode_ns."""
    index: int
    error: Optional[SkinserveError] = None
    answer: Optional[Answer] = None
    positions: Optional[FloatArray] = None
    normals: Optional[FloatArray] = None
    tangents: Optional[FloatArray] = None
    timing: Dict[str, int] = dataclasses.field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.error is None


def check_characters(characters: Sequence[Character],
                     joint_count: Callable[[str], Optional[int]]) -> List[Optional[int]]:
    """Each character's crowd size (None: a single palette or a pose), its palette checked
    against its mesh's joints (when this client knows them) or its pose's shape, and its
    encoding by name."""
    characters = list(characters)
    if not characters:
        raise ValueError("characters: empty, expected at least one Character")
    crowds: List[Optional[int]] = []
    for i, c in enumerate(characters):
        if not isinstance(c, Character):
            raise ValueError(f"characters[{i}]: {type(c).__name__}, expected skinserve.Character")
        _requests.check_encoding(c.encoding)
        if (c.palette is None) == (c.pose is None):
            raise ValueError(f"characters[{i}]: give a palette or a pose (one of them), "
                             f"not {'both' if c.pose is not None else 'neither'}")
        if c.pose is not None:
            _pose.check_pose(f"characters[{i}].pose", c.pose)
            crowds.append(None)
            continue
        crowds.append(_arrays.check_palette(f"characters[{i}].palette", c.palette,
                                            joint_count(c.mesh_id)))
    return crowds


def tick_request(characters: Sequence[Character], crowds: Sequence[Optional[int]], frame: int,
                 slot_offset: int = 0) -> pb.SkinRequest:
    """The tick's SkinRequest: `frame`, and each character's own request (no frame of its
    own); region characters at their offset + slot_offset."""
    request = pb.SkinRequest(frame=frame)
    for c, crowd in zip(characters, crowds):
        character = _requests.skin_request(
            c.mesh_id, c.palette, crowd, 0, c.backend, c.want_normals, c.encoding, c.region,
            c.offset + slot_offset, c.morph_weights, c.want_tangents)
        if c.pose is not None:
            _pose.set_pose(character, c.pose)
        request.characters.append(character)
    return request


def region_stride(characters_per_tick: Sequence[Sequence[Character]],
                  crowds: Sequence[Sequence[Optional[int]]],
                  vertex_count: Callable[[str], int]) -> int:
    """A stream of ticks: the bytes from 0 to the end of the furthest region character's
    range, rounded up, which is the distance between the slots of ticks in flight."""
    end = 0
    for characters, tick_crowds in zip(characters_per_tick, crowds):
        for c, crowd in zip(characters, tick_crowds):
            if c.region is None:
                continue
            size = 4 if c.encoding == "float32" else 2
            end = max(end, c.offset + _shared_memory.frame_bytes(
                vertex_count(c.mesh_id), crowd or 1, size, c.want_normals, c.want_tangents))
    return _shared_memory.round_up(end)


def stream_regions(ticks: Sequence[Sequence[Character]],
                   crowds: Sequence[Sequence[Optional[int]]],
                   vertex_count: Callable[[str], int], window: int
                   ) -> Tuple[int, Optional[SharedMemoryRegion]]:
    """A stream of ticks' slot stride (region_stride) and a region its characters name
    (None: none does); every region named must hold `window` slots."""
    stride = region_stride(ticks, crowds, vertex_count)
    regions = {id(c.region): c.region for t in ticks for c in t if c.region is not None}
    for r in regions.values():
        if window * stride > r.byte_size:
            raise ValueError(f"region: {r.byte_size} bytes, fewer than {window} ticks in "
                             f"flight of {stride} bytes")
    return stride, next(iter(regions.values()), None)


class TickAnswer:
    """A tick's parts assembled: every character's vertex parts (SkinResponse.character
    says whose), then the final part whose `tick` says how each ended. The same interface
    as Frame (add_part, error), so that the clients' streams carry ticks too."""

    def __init__(self, characters: Sequence[Character], crowds: Sequence[Optional[int]],
                 frame: int, slot_offset: int = 0) -> None:
        self.characters, self.frame, self.slot_offset = list(characters), frame, slot_offset
        self.frames = [Frame(crowd) for crowd in crowds]
        self.error: Optional[Any] = None  # (grpc.StatusCode, message): the tick failed whole
        self.results: List[CharacterResult] = []

    def answered(self) -> List[CharacterResult]:
        """The characters' results; raises SkinserveError when the tick failed whole or its
        answer never ended."""
        if self.error is not None:
            raise SkinserveError(self.error[0], self.error[1], self.frame)
        if not self.results and self.characters:
            raise self._fail("no final part")
        return self.results

    def _fail(self, what: str) -> SkinserveError:
        return SkinserveError(grpc.StatusCode.INTERNAL, f"malformed tick answer: {what}",
                              self.frame)

    def add_part(self, part: pb.SkinResponse, *_: Any) -> None:
        if part.HasField("tick"):
            self._finish(part.tick)
        elif part.HasField("error"):  # the tick failed whole (refused)
            self.error = (status_code(part.error.code), part.error.message)
        elif part.last:
            raise self._fail("the final part has no TickAnswer")
        else:
            if part.character >= len(self.frames):
                raise self._fail(f"a part of character {part.character}, the tick has "
                                 f"{len(self.frames)}")
            c = self.characters[part.character]
            self.frames[part.character].add_part(part, c.want_normals, None)

    def _finish(self, tick: pb.TickAnswer) -> None:
        if len(tick.characters) != len(self.characters):
            raise self._fail(f"{len(tick.characters)} characters answered, "
                             f"{len(self.characters)} sent")
        self.results = [self._result(i, header) for i, header in enumerate(tick.characters)]

    def _result(self, i: int, header: pb.SkinResponse) -> CharacterResult:
        c, frame = self.characters[i], self.frames[i]
        timing = {"queued_ns": header.timing.queued_ns, "compute_ns": header.timing.compute_ns,
                  "encode_ns": header.timing.encode_ns}
        if header.HasField("error"):
            return CharacterResult(i, SkinserveError(status_code(header.error.code),
                                                     header.error.message, self.frame),
                                   timing=timing)
        if header.HasField("region_write"):
            final = pb.SkinResponse()
            final.CopyFrom(header)
            final.last = True
            frame.add_part(final, c.want_normals, c.region)
        elif frame.positions is None or frame._next != (max(header.instances, 1), 0):
            raise self._fail(f"character {i} answered without all its vertices")
        answer = frame.result(c.want_normals, c.want_tangents)
        parts: Tuple[Any, ...] = answer if isinstance(answer, tuple) else (answer,)
        return CharacterResult(i, None, answer, parts[0],
                               parts[1] if len(parts) > 1 else None,
                               parts[2] if len(parts) > 2 else None, timing)
