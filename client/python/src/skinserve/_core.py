"""The clients' core, free of any transport: the settings, the meshes uploaded through a
client (to upload again), the checked requests, and the decisions taken between calls
(re-upload and resend on NOT_FOUND, resume a stream, give up). Skeletons and clips are
remembered as meshes are: a pose frame answered NOT_FOUND naming one uploads it again. Client (grpc's blocking
stub, threads) and AsyncClient (grpc.aio, coroutines) add only the calls and the waiting."""
from typing import (Any, Callable, Dict, Iterable, List, Optional, Sequence, Tuple,
                    Union)

import grpc
import numpy as np
import numpy.typing as npt

from . import _arrays, _channel, _pose, _requests, _tick
from ._errors import SkinserveError, rpc_error
from ._frame import Answer, Frame
from ._lost_upload import Lost, lost_upload
from ._morph import FrameWeights
from ._pose import PaletteOrPose, Pose
from ._service import SkinningStub
from ._shared_memory import SharedMemoryRegion
from ._tick import Character, CharacterResult
from .v1 import skinning_pb2 as pb

Ended = List[Tuple[Any, str]]  # why a StreamSkin call ended early: (grpc.StatusCode, message)


class ClientCore:
    """What both clients are but their calls. `_grpc`, set by each client, is the module
    whose channels it opens: grpc or grpc.aio."""

    _grpc: Any

    def __init__(self, target: str, max_reuploads: int = 8, max_reconnects: int = 3,
                 tls_ca: Optional[str] = None, tls_cert: Optional[str] = None,
                 tls_key: Optional[str] = None, tls_server_name: Optional[str] = None,
                 timeout: Optional[float] = 30.0, upload_timeout: Optional[float] = 300.0,
                 stream_idle_timeout: Optional[float] = 30.0,
                 keepalive: Optional[float] = 10.0, keepalive_timeout: float = 5.0) -> None:
        self.target = target
        self.max_reuploads, self.max_reconnects = max_reuploads, max_reconnects
        self.timeout, self.upload_timeout = timeout, upload_timeout
        self.stream_idle_timeout = stream_idle_timeout
        credentials = _channel.credentials(tls_ca, tls_cert, tls_key, tls_server_name)
        options = _channel.options(keepalive, keepalive_timeout, tls_server_name)
        if credentials is None:
            self._channel = self._grpc.insecure_channel(target, options=options)
        else:
            self._channel = self._grpc.secure_channel(target, credentials, options=options)
        self._stub = SkinningStub(self._channel)
        # mesh id -> (requests to upload it again, joint count, vertex count)
        self._meshes: Dict[str, Tuple[List[pb.UploadMeshRequest], int, int]] = {}
        # skeleton id -> its request; clip id -> its request (which names its skeleton)
        self._skeletons: Dict[str, pb.UploadSkeletonRequest] = {}
        self._clips: Dict[str, pb.UploadClipRequest] = {}

    # ---- meshes -----------------------------------------------------------------------
    def _remember(self, requests: List[pb.UploadMeshRequest], info: pb.MeshInfo) -> str:
        """Keeps an uploaded mesh's requests (to upload it again) and returns its id."""
        self._meshes[info.mesh_id] = (requests, requests[0].header.joint_count,
                                      requests[0].header.vertex_count)
        return str(info.mesh_id)

    def _joint_count(self, mesh_id: str) -> Optional[int]:
        known = self._meshes.get(mesh_id)
        return known[1] if known else None

    def _known_vertex_count(self, mesh_id: str) -> Optional[int]:
        known = self._meshes.get(mesh_id)
        return known[2] if known else None

    def _upload_again(self, lost: Lost, error: SkinserveError) -> Lost:
        """`lost` when this client uploaded it (and can again), else raises `error`."""
        if not self._uploaded(lost):
            raise error  # not uploaded through this client: nothing to send again
        return lost

    def _uploaded(self, lost: Lost) -> bool:
        """Whether this client uploaded what `lost` names (and can upload it again)."""
        if lost.kind == "skeleton":
            return lost.id in self._skeletons
        if lost.kind == "clip":
            return lost.id in self._clips
        return lost.id in self._meshes

    def _retry_frame(self, e: Any, attempt: int, frame: int, mesh_id: str) -> Lost:
        """A frame's call failed with the grpc error `e` on attempt `attempt`: what to upload
        again before it is resent (NOT_FOUND, attempts left), else raises the
        SkinserveError."""
        error = rpc_error(e, frame)
        if e.code() != grpc.StatusCode.NOT_FOUND or attempt == self.max_reuploads:
            raise error from None
        return self._upload_again(lost_upload(error.message, mesh_id), error)

    # ---- skeletons and clips ------------------------------------------------------------
    def _remember_skeleton(self, request: pb.UploadSkeletonRequest, skeleton_id: str) -> str:
        self._skeletons.setdefault(skeleton_id, request)
        return skeleton_id

    def _remember_clip(self, request: pb.UploadClipRequest, info: pb.ClipInfo) -> pb.ClipInfo:
        self._clips.setdefault(info.clip_id, request)
        return info

    def _forget_clip(self, clip_id: str) -> None:
        self._clips.pop(clip_id, None)

    def _skeleton_uploads(self, skeleton_id: str) -> List[Any]:
        """What uploads a lost skeleton again: its request, then those of its clips this
        client uploaded (the server lost them with it). NOT_FOUND when this client never
        uploaded the skeleton."""
        if skeleton_id not in self._skeletons:
            raise SkinserveError(grpc.StatusCode.NOT_FOUND,
                                 f"skeleton '{skeleton_id}' is not on the server and this "
                                 "client never uploaded it")
        return [self._skeletons[skeleton_id]] + [
            c for c in self._clips.values() if c.skeleton_id == skeleton_id]

    # ---- shared memory, frames ----------------------------------------------------------
    @staticmethod
    def _region_and_name(region_or_name: Union[SharedMemoryRegion, str]
                         ) -> Tuple[Optional[SharedMemoryRegion], Optional[str]]:
        if isinstance(region_or_name, SharedMemoryRegion):
            return region_or_name, region_or_name.name
        return None, region_or_name

    def _skin_request(self, mesh_id: str, palette: npt.NDArray[np.float32],
                      backend: Optional[str], want_normals: bool, encoding: str, frame: int,
                      region: Optional[SharedMemoryRegion], offset: int,
                      morph_weights: Optional[FrameWeights], want_tangents: bool
                      ) -> Tuple[Optional[int], pb.SkinRequest]:
        """One frame's crowd size (None: a single palette) and request, checked."""
        crowd = _arrays.check_palette("palette", palette, self._joint_count(mesh_id))
        return crowd, _requests.skin_request(mesh_id, palette, crowd, frame, backend,
                                             want_normals, encoding, region, offset,
                                             morph_weights, want_tangents)

    def _stream_idle_ended(self) -> Tuple[Any, str]:
        return (grpc.StatusCode.DEADLINE_EXCEEDED,
                f"no answer for {self.stream_idle_timeout} s with frames in flight "
                "(stream_idle_timeout)")

    # ---- ticks ----------------------------------------------------------------------------
    def _tick_reuploads(self, characters: Sequence[Character],
                        results: Sequence[CharacterResult]) -> Tuple[List[int], List[Lost]]:
        """The characters answered NOT_FOUND for what this client can upload again (a mesh,
        or a skeleton or clip of a pose), and those uploads, each once."""
        missing: List[int] = []
        lost: List[Lost] = []
        for r in results:
            if r.error is None or r.error.code != grpc.StatusCode.NOT_FOUND:
                continue
            what = lost_upload(r.error.message, characters[r.index].mesh_id)
            if self._uploaded(what):
                missing.append(r.index)
                if what not in lost:
                    lost.append(what)
        return missing, lost


def new_frame(requests: Sequence[pb.SkinRequest],
              make_frame: Optional[Callable[[int], Any]]) -> Callable[[int], Any]:
    """What assembles the answer to requests[i] in a StreamSkin call: `make_frame(i)`
    (ticks), else a Frame; past the end, one never filled."""
    def make(i: int) -> Any:
        if make_frame is not None:
            return make_frame(i)
        return Frame((requests[i].instances or None) if i < len(requests) else None)
    return make


def merge_tick_results(results: List[CharacterResult], missing: Sequence[int],
                       again: Sequence[CharacterResult]) -> None:
    """Puts the results of the characters sent again (`missing`, in order) in their
    places."""
    for i, result in zip(missing, again):
        result.index = i
        results[i] = result


class FrameStream:
    """Client.stream's frames but for the calls: the requests, checked before the first is
    sent, how far the answers have come, and what ends each StreamSkin call: a NOT_FOUND
    frame (the mesh is uploaded again, the stream resumes from it), an early end
    (UNAVAILABLE, idle: a new call resumes, up to max_reconnects times), or an error."""

    def __init__(self, core: ClientCore, mesh_id: str,
                 palettes: Iterable[PaletteOrPose],
                 backend: Optional[str],
                 want_normals: bool, encoding: str, window: int,
                 region: Optional[SharedMemoryRegion],
                 morph_weights: Optional[Iterable[Optional[FrameWeights]]],
                 want_tangents: bool) -> None:
        self._core, self.mesh_id, self.window, self.region = core, mesh_id, window, region
        self._args = (backend, want_normals, encoding, want_tangents)
        self._palettes = list(palettes)
        joints = core._joint_count(mesh_id)
        self._crowds = [self._check_frame(i, palette, joints)
                        for i, palette in enumerate(self._palettes)]
        _requests.check_window(window)
        _requests.check_encoding(encoding)
        self._weights = _requests.stream_weights(morph_weights, len(self._palettes))
        self.requests: List[pb.SkinRequest] = []
        self.next_frame, self._reuploads, self._reconnects = 0, 0, 0
        self.ended: Ended = []
        self._restart: Optional[SkinserveError] = None

    @staticmethod
    def _check_frame(i: int, palette: PaletteOrPose, joints: Optional[int]) -> Optional[int]:
        """Frame i's crowd size; a pose frame (one instance) has none."""
        if isinstance(palette, Pose):
            _pose.check_pose(f"palettes[{i}]", palette)
            return None
        return _arrays.check_palette(f"palettes[{i}]", palette, joints)

    def _request(self, i: int, stride: int) -> pb.SkinRequest:
        backend, want_normals, encoding, want_tangents = self._args
        palette = self._palettes[i]
        pose = palette if isinstance(palette, Pose) else None
        array = None if isinstance(palette, Pose) else palette
        request = _requests.skin_request(
            self.mesh_id, array, self._crowds[i], i, backend,
            want_normals, encoding, self.region, (i % self.window) * stride, self._weights[i],
            want_tangents)
        if pose is not None:
            _pose.set_pose(request, pose)
        return request

    def build(self, vertices: int) -> None:
        """The requests; `vertices`, the mesh's vertex count, lays out the region's slots
        (unused without a region)."""
        _, want_normals, encoding, want_tangents = self._args
        stride = 0
        if self.region is not None:
            stride = _requests.region_stride(vertices, self._crowds, want_normals, encoding,
                                             self.window, self.region, want_tangents)
        self.requests = [self._request(i, stride) for i in range(len(self._palettes))]

    @property
    def done(self) -> bool:
        return self.next_frame >= len(self.requests)

    def open(self) -> Ended:
        """A new StreamSkin call from next_frame: returns the list its early end goes in."""
        self._restart, self.ended = None, []
        return self.ended

    def answer(self, index: int, frame: Any) -> Optional[Answer]:
        """Frame `index` answered: its arrays, or None when the mesh was NOT_FOUND (end
        the call: closed() says what to upload before the next); raises its error when
        it is not to be retried."""
        if frame.error is None:
            self.next_frame = index + 1
            _, want_normals, _, want_tangents = self._args
            result: Answer = frame.result(want_normals, want_tangents)
            return result
        code, message = frame.error
        error = SkinserveError(code, message, index)
        if code != grpc.StatusCode.NOT_FOUND or self._reuploads >= self._core.max_reuploads:
            raise error
        self._restart = error
        return None

    def closed(self) -> Optional[Lost]:
        """The call ended: what to upload again before the next call (the mesh, or the
        skeleton or clip of a pose, resuming from the frame that was NOT_FOUND), or None;
        raises when the stream ended early more than max_reconnects times."""
        if self._restart is not None:
            self._reuploads += 1
            return self._core._upload_again(lost_upload(self._restart.message, self.mesh_id),
                                            self._restart)
        if not self.done:  # the call ended UNAVAILABLE or idle early
            self._reconnects += 1
            if self._reconnects > self._core.max_reconnects:
                code, message = self.ended[0] if self.ended else (grpc.StatusCode.UNAVAILABLE,
                                                                  "")
                raise SkinserveError(code, f"stream ended {self._reconnects} times, the "
                                     f"last: {message}", self.next_frame)
        return None


class TickStream:
    """Client.stream_ticks but for the calls: the ticks checked, their requests (region
    characters in slot i % window), their answers' assemblers, and the end."""

    def __init__(self, core: ClientCore, ticks: Iterable[Sequence[Character]],
                 window: int) -> None:
        self.window = window
        self.ticks = [list(t) for t in ticks]
        self.crowds = [_tick.check_characters(t, core._joint_count) for t in self.ticks]
        _requests.check_window(window)
        self.requests: List[pb.SkinRequest] = []
        self.region: Optional[SharedMemoryRegion] = None
        self._stride = 0
        self.ended: Ended = []

    def region_meshes(self) -> List[str]:
        """The meshes whose vertex count lays out the region slots, in order."""
        return list(dict.fromkeys(c.mesh_id for t in self.ticks for c in t
                                  if c.region is not None))

    def build(self, vertex_counts: Dict[str, int]) -> None:
        """The requests, given region_meshes()' vertex counts."""
        self._stride, self.region = _tick.stream_regions(self.ticks, self.crowds,
                                                         vertex_counts.__getitem__,
                                                         self.window)
        self.requests = [_tick.tick_request(t, k, i, self.slot_offset(i))
                         for i, (t, k) in enumerate(zip(self.ticks, self.crowds))]

    def slot_offset(self, index: int) -> int:
        return (index % self.window) * self._stride

    def make_answer(self, i: int) -> _tick.TickAnswer:
        if i >= len(self.ticks):
            return _tick.TickAnswer([], [], i)
        return _tick.TickAnswer(self.ticks[i], self.crowds[i], i)

    def check_finished(self, answered: int) -> None:
        """Raises when the call ended with ticks unanswered."""
        if answered < len(self.ticks):
            code, message = self.ended[0] if self.ended else (grpc.StatusCode.UNAVAILABLE, "")
            raise SkinserveError(code, f"stream of ticks ended: {message}", answered)
