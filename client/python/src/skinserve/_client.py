"""Client: the Skinning service as NumPy arrays in, NumPy arrays out."""
import contextlib
import queue
import threading
import time

import grpc
import numpy as np

from . import _arrays, _encoding, _shared_memory
from .v1 import skinning_pb2 as pb
from .v1 import skinning_pb2_grpc as pb_grpc

_CHUNK_BYTES = 1 << 20
_STREAM_WINDOW_BYTES = 4 << 20
_ENCODINGS = {"float32": pb.ENCODING_FLOAT32, "float16": pb.ENCODING_FLOAT16,
              "snorm16": pb.ENCODING_SNORM16}


class SkinserveError(Exception):
    """A call or a frame the server answered with an error: `code` (grpc.StatusCode) and
    the server's own message."""

    def __init__(self, code, message, frame=None):
        self.code, self.message, self.frame = code, message, frame
        where = f"frame {frame}: " if frame is not None else ""
        super().__init__(f"{where}{code.name}: {message}")


def _status_code(value):
    for code in grpc.StatusCode:
        if code.value[0] == value:
            return code
    return grpc.StatusCode.UNKNOWN


_HINTS = [  # gRPC's reasons for a failed connection, and what TLS setting likely caused it
    ("Socket closed", "the server closed the connection at once: a TLS server refuses "
     "plaintext clients (give tls_ca), a mutual-TLS server refuses clients without a "
     "certificate (give tls_cert and tls_key)"),
    ("wrong version number", "the server does not speak TLS there (plaintext, or a unix: "
     "address): leave out tls_ca, tls_cert and tls_key"),
    ("certificate verify failed", "the server's certificate is not signed by the CA of tls_ca"),
]


def _rpc_error(error, frame=None):
    details = error.details() or ""
    if error.code() == grpc.StatusCode.UNAVAILABLE:
        for reason, hint in _HINTS:
            if reason in details:
                details = f"{details} (hint: {hint})"
                break
    return SkinserveError(error.code(), details, frame)


class _Frame:
    """One frame's parts, assembled into float32 arrays: (V, 3) for a single palette, or
    (K, V, 3) for a crowd of K instances (`crowd` = K). Parts come instance by instance,
    each in vertex order, or several whole instances in one part (packed:
    SkinResponse.instance_count); one that does not fit the frame fails it (INTERNAL)."""

    def __init__(self, crowd=None):
        self.crowd = crowd
        self.positions = self.normals = None
        self.error = None
        self._next = (0, 0)  # the (instance, first vertex) the next part must start at

    def _fail(self, part, what):
        raise SkinserveError(grpc.StatusCode.INTERNAL, f"malformed answer: {what}", part.frame)

    def add(self, part, want_normals):
        if part.HasField("error"):
            self.error = (_status_code(part.error.code), part.error.message)
            return
        instances = max(part.instances, 1)  # a server without crowds leaves it 0
        if instances != (self.crowd or 1):
            self._fail(part, f"{instances} instances, {self.crowd or 1} asked for")
        if self.positions is None:
            shape = (instances, part.total_vertices, 3)
            self.positions = np.empty(shape, dtype=np.float32)
            if want_normals:
                self.normals = np.empty(shape, dtype=np.float32)
        total = self.positions.shape[1]
        packed = max(part.instance_count, 1)  # whole instances in this part
        end = part.first_vertex + part.vertex_count
        if (part.instance, part.first_vertex) != self._next or part.total_vertices != total \
                or end > total or part.instance + packed > instances \
                or (packed > 1 and (part.first_vertex != 0 or end != total)):
            self._fail(part, f"part of instance {part.instance} ({packed} packed), vertices "
                       f"[{part.first_vertex}, {end}) of {part.total_vertices}, expected "
                       f"instance {self._next[0]} from vertex {self._next[1]} of {total}")
        if packed > 1 and part.encoding == _encoding.SNORM16 \
                and len(part.instance_bounds) != packed:
            self._fail(part, f"{packed} instances in the part but "
                       f"{len(part.instance_bounds)} instance_bounds")
        self._next = (part.instance + packed, 0) if end == total else (part.instance, end)
        if part.last and self._next != (instances, 0):
            self._fail(part, f"the frame ended at instance {self._next[0]}, vertex "
                       f"{self._next[1]}")
        positions, normals = memoryview(part.positions), memoryview(part.normals)
        if len(positions) % packed or len(normals) % packed:
            self._fail(part, f"{len(positions)} and {len(normals)} bytes of positions and "
                       f"normals for {packed} instances")
        rows = slice(part.first_vertex, end)
        for j in range(packed):
            k = part.instance + j
            b = part.instance_bounds[j] if packed > 1 and part.encoding == _encoding.SNORM16 \
                else part.bounds
            bounds = (b.min_x, b.min_y, b.min_z, b.max_x, b.max_y, b.max_z)
            p_size, n_size = len(positions) // packed, len(normals) // packed
            self.positions[k, rows] = _encoding.decode_values(
                positions[j * p_size:(j + 1) * p_size], part.encoding, part.vertex_count, bounds)
            if want_normals:
                self.normals[k, rows] = _encoding.decode_values(
                    normals[j * n_size:(j + 1) * n_size], part.encoding, part.vertex_count,
                    normals=True)

    def add_region(self, part, want_normals, region):
        """The frame's one part when it went into `region`: arrays that view the region
        (float32 and float16: no copy; snorm16 positions are decoded into new arrays)."""
        write = part.region_write
        if region is None or write.region != region.name:
            self._fail(part, f"answered in region '{write.region}', which the frame did not name")
        instances, vertices = max(part.instances, 1), part.total_vertices
        if instances != (self.crowd or 1) or not part.last:
            self._fail(part, f"{instances} instances in region '{write.region}'")
        dtype = {_encoding.FLOAT32: "<f4", _encoding.FLOAT16: "<f2",
                 _encoding.SNORM16: "<i2"}[part.encoding]
        count = instances * vertices * 3
        size = count * np.dtype(dtype).itemsize
        if write.instance_bytes * instances != size or write.end_offset > region.byte_size \
                or write.positions_offset + size > region.byte_size:
            self._fail(part, f"ranges of region '{write.region}' do not fit the frame")

        def view(offset, normals):
            values = np.frombuffer(region.buffer, dtype=dtype, count=count, offset=offset)
            values = values.reshape(instances, vertices, 3)
            if part.encoding != _encoding.SNORM16:
                return values
            out = np.empty(values.shape, dtype=np.float32)
            for k in range(instances):
                b = part.instance_bounds[k]
                out[k] = _encoding.decode_values(
                    values[k].tobytes(), part.encoding, vertices,
                    (b.min_x, b.min_y, b.min_z, b.max_x, b.max_y, b.max_z), normals=normals)
            return out

        self.positions = view(write.positions_offset, False)
        if want_normals:
            self.normals = view(write.normals_offset, True)

    def result(self, want_normals):
        positions, normals = self.positions, self.normals
        if self.crowd is None:
            positions = positions[0]
            normals = None if normals is None else normals[0]
        return (positions, normals) if want_normals else positions


def _read(option, path):
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as e:
        raise ValueError(f"{option} '{path}': cannot read the file: {e.strerror}") from None
    if b"-----BEGIN " not in data:
        raise ValueError(f"{option} '{path}': no PEM block (-----BEGIN ...) in the file")
    return data


class _IdleWatchdog:
    """Cancels `call` when no answer came for `limit` seconds while one was awaited (see the
    C++ library's IdleWatchdog): a stream has no deadline, but must not wait for ever on a
    server that stopped answering."""

    def __init__(self, call, limit):
        self._call, self._limit = call, limit
        self._last, self._awaiting = time.monotonic(), False
        self._done = threading.Event()
        self.fired = False
        if limit:
            self._thread = threading.Thread(target=self._watch, daemon=True)
            self._thread.start()

    def answered(self):
        self._last = time.monotonic()

    def awaiting(self, value):
        if value and not self._awaiting:
            self._last = time.monotonic()
        self._awaiting = value

    def _watch(self):
        while not self._done.is_set():
            idle = time.monotonic() - self._last
            if self._awaiting and idle >= self._limit:
                self.fired = True
                self._call.cancel()
                return
            self._done.wait(self._limit - idle if self._awaiting else self._limit)

    def stop(self):
        self._done.set()


class Client:
    """A connection to skinserve at `target` ("host:port", or any gRPC target such as
    "dns:///skinserve.default.svc:50051", balanced with round_robin).

    TLS: `tls_ca` (the PEM file of the CA that signed the server's certificate) turns it on;
    `tls_cert` and `tls_key` present this client's certificate (mutual TLS);
    `tls_server_name` is the name the server's certificate must carry when the target's
    host is not it (an IP address). unix: targets are plaintext on the server's side.

    Every call has a deadline: `timeout` seconds (uploads: `upload_timeout`); a stream whose
    frames wait `stream_idle_timeout` seconds without an answer ends (DEADLINE_EXCEEDED) and
    resumes on a new stream like one ended UNAVAILABLE. With calls open the channel pings the
    server every `keepalive` seconds and gives up on one that does not answer within
    `keepalive_timeout` (UNAVAILABLE). None: no limit.

    Meshes uploaded through this client are remembered: a frame answered NOT_FOUND (the
    replica evicted the mesh, or the call landed on another replica) uploads the mesh
    again and resends the frame, as the C++ client library does.
    """

    def __init__(self, target, max_reuploads=8, max_reconnects=3, tls_ca=None, tls_cert=None,
                 tls_key=None, tls_server_name=None, timeout=30.0, upload_timeout=300.0,
                 stream_idle_timeout=30.0, keepalive=10.0, keepalive_timeout=5.0):
        self.target = target
        self.max_reuploads, self.max_reconnects = max_reuploads, max_reconnects
        self.timeout, self.upload_timeout = timeout, upload_timeout
        self.stream_idle_timeout = stream_idle_timeout
        # Flow control as the C++ library's MakeChannel: a fixed 4 MiB receive window per
        # stream, BDP probing off (with probing, crowd frames of several 1 MiB parts
        # stalled now and then; docs/client-library.md, "Channels").
        options = [("grpc.service_config",
                    '{"loadBalancingConfig": [{"round_robin": {}}]}'),
                   ("grpc.http2.bdp_probe", 0),
                   ("grpc.http2.lookahead_bytes", _STREAM_WINDOW_BYTES)]
        if keepalive:
            # Pings also while this side sends nothing (gRPC stops after two otherwise).
            options += [("grpc.keepalive_time_ms", int(keepalive * 1000)),
                        ("grpc.keepalive_timeout_ms", int(keepalive_timeout * 1000)),
                        ("grpc.http2.max_pings_without_data", 0),
                        ("grpc.keepalive_permit_without_calls", 0)]
        if tls_ca is None and (tls_cert or tls_key or tls_server_name):
            raise ValueError("tls_cert, tls_key and tls_server_name need tls_ca: the CA that "
                             "signed the server's certificate")
        if bool(tls_cert) != bool(tls_key):
            raise ValueError(f"tls_cert and tls_key go together: tls_cert is {tls_cert!r}, "
                             f"tls_key {tls_key!r}")
        if tls_ca is None:
            self._channel = grpc.insecure_channel(target, options=options)
        else:
            credentials = grpc.ssl_channel_credentials(
                root_certificates=_read("tls_ca", tls_ca),
                private_key=_read("tls_key", tls_key) if tls_key else None,
                certificate_chain=_read("tls_cert", tls_cert) if tls_cert else None)
            if tls_server_name:
                options.append(("grpc.ssl_target_name_override", tls_server_name))
            self._channel = grpc.secure_channel(target, credentials, options=options)
        self._stub = pb_grpc.SkinningStub(self._channel)
        self._meshes = {}  # mesh id -> (requests to upload it again, joint count)

    def close(self):
        self._channel.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # ---- meshes -----------------------------------------------------------------------
    def upload(self, positions, joints, weights, normals=None, normalize_weights=False,
               joint_count=None):
        """Stores a mesh and returns its id (the SHA-256 of its content).

        positions, normals: float32 (V, 3); joints: uint16 (V, B); weights: float32 (V, B),
        1 <= B <= 8. Weights must sum to 1 per vertex unless normalize_weights is set.
        joint_count: the palettes' length (default: the largest joint id + 1).
        """
        _arrays.check_mesh(positions, joints, weights, normals)
        used = int(joints.max()) + 1
        if joint_count is None:
            joint_count = used
        elif not isinstance(joint_count, int) or joint_count < used:
            raise ValueError(f"joint_count: {joint_count!r}, expected an int >= {used} "
                             f"(joints refers to joint {used - 1})")
        header = pb.MeshHeader(
            vertex_count=positions.shape[0], influences=joints.shape[1],
            joint_count=joint_count, has_normals=normals is not None,
            weight_policy=(pb.WEIGHT_POLICY_NORMALIZE if normalize_weights
                           else pb.WEIGHT_POLICY_REJECT))
        requests = [pb.UploadMeshRequest(header=header)]
        arrays = [(pb.MESH_ARRAY_POSITIONS, positions, "f4"),
                  (pb.MESH_ARRAY_NORMALS, normals, "f4"),
                  (pb.MESH_ARRAY_JOINTS, joints, "u2"),
                  (pb.MESH_ARRAY_WEIGHTS, weights, "f4")]
        for kind, array, dtype in arrays:
            if array is None:
                continue
            data = _arrays.little_endian_bytes(array, dtype)
            itemsize = np.dtype(dtype).itemsize
            for offset in range(0, len(data), _CHUNK_BYTES):
                requests.append(pb.UploadMeshRequest(chunk=pb.MeshChunk(
                    array=kind, offset=offset // itemsize,
                    data=data[offset:offset + _CHUNK_BYTES])))
        info = self._upload(requests)
        self._meshes[info.mesh_id] = (requests, header.joint_count)
        return info.mesh_id

    def _upload(self, requests):
        try:
            return self._stub.UploadMesh(iter(requests), timeout=self.upload_timeout)
        except grpc.RpcError as e:
            raise _rpc_error(e) from None

    def _reupload(self, mesh_id, error):
        if mesh_id not in self._meshes:
            raise error  # not uploaded through this client: nothing to send again
        self._upload(self._meshes[mesh_id][0])

    def _joint_count(self, mesh_id):
        known = self._meshes.get(mesh_id)
        return known[1] if known else None

    # ---- frames -------------------------------------------------------------------------
    def _request(self, mesh_id, palette, crowd, frame, backend, want_normals, encoding,
                 region=None, offset=0):
        if encoding not in _ENCODINGS:
            raise ValueError(f"encoding: '{encoding}', expected one of {sorted(_ENCODINGS)}")
        request = pb.SkinRequest(mesh_id=mesh_id, backend=backend or "", frame=frame,
                                 palette=_arrays.little_endian_bytes(palette, "f4"),
                                 want_normals=want_normals, encoding=_ENCODINGS[encoding],
                                 instances=crowd or 0, pack_instances=True)
        if region is not None:
            if region.name is None:
                raise ValueError("region: not registered (Client.register_region)")
            request.output.region = region.name
            request.output.offset = offset
        return request

    def _add(self, frame, part, want_normals, region):
        if part.HasField("region_write"):
            frame.add_region(part, want_normals, region)
        else:
            frame.add(part, want_normals)

    # ---- shared memory (same host) ------------------------------------------------------
    def register_region(self, region, name=None):
        """Registers a SharedMemoryRegion with the server (which must run on this host,
        with the region's directory as its --shm-dir) under `name` (default: its key).
        Frames naming it are skinned straight into it. Returns the server's RegionInfo."""
        name = name or region.key
        try:
            info = self._stub.RegisterRegion(pb.RegisterRegionRequest(
                name=name, key=region.key, byte_size=region.byte_size), timeout=self.timeout)
        except grpc.RpcError as e:
            raise _rpc_error(e) from None
        region.name = name
        return info

    def unregister_region(self, region_or_name):
        """Returns once the server has unmapped the region: it writes there no more."""
        name = getattr(region_or_name, "name", region_or_name)
        try:
            self._stub.UnregisterRegion(pb.UnregisterRegionRequest(name=name),
                                        timeout=self.timeout)
        except grpc.RpcError as e:
            raise _rpc_error(e) from None
        if hasattr(region_or_name, "name"):
            region_or_name.name = None

    def regions(self):
        """The server's registered regions: a list of dicts (name, key, byte_size, ...)."""
        try:
            response = self._stub.ListRegions(pb.ListRegionsRequest(), timeout=self.timeout)
        except grpc.RpcError as e:
            raise _rpc_error(e) from None
        return [{"name": r.name, "key": r.key, "byte_size": r.byte_size,
                 "frames_written": r.frames_written, "idle_seconds": r.idle_seconds}
                for r in response.regions]

    def _frame_bytes(self, mesh_id, crowd, want_normals, encoding):
        try:
            info = self._stub.GetMesh(pb.GetMeshRequest(mesh_id=mesh_id), timeout=self.timeout)
        except grpc.RpcError as e:
            raise _rpc_error(e) from None
        size = 4 if encoding == "float32" else 2
        return _shared_memory.frame_bytes(info.vertex_count, crowd or 1, size, want_normals)

    def skin(self, mesh_id, palette, backend=None, want_normals=False, encoding="float32",
             frame=0, region=None, offset=0):
        """One frame: palette float32 (J, 3, 4) -> positions (V, 3) float32, or
        (positions, normals) with want_normals. A crowd, palettes (K, J, 3, 4) of K
        instances of the mesh, is one request and answers (K, V, 3) arrays.

        encoding: how the server sends the vertices ("float32", "float16" or "snorm16",
        see docs/serving/encodings.md); the answer is decoded to float32.

        region: a registered SharedMemoryRegion: the server writes the frame into it from
        `offset` (a multiple of 64) and the answer views it: float32 arrays (float16 ones
        with encoding="float16"; snorm16 is decoded into new arrays), valid until the
        region's bytes are written again."""
        crowd = _arrays.check_palette("palette", palette, self._joint_count(mesh_id))
        request = self._request(mesh_id, palette, crowd, frame, backend, want_normals, encoding,
                                region, offset)
        for attempt in range(self.max_reuploads + 1):
            result = _Frame(crowd)
            try:
                for part in self._stub.Skin(request, timeout=self.timeout):
                    self._add(result, part, want_normals, region)
                return result.result(want_normals)
            except grpc.RpcError as e:
                error = _rpc_error(e, frame)
                if e.code() != grpc.StatusCode.NOT_FOUND or attempt == self.max_reuploads:
                    raise error from None
                self._reupload(mesh_id, error)
        raise AssertionError("unreachable")

    def stream(self, mesh_id, palettes, backend=None, want_normals=False, encoding="float32",
               window=8, region=None):
        """Frame after frame over one StreamSkin call: yields each frame's positions (or
        (positions, normals)) in order. `palettes`: a sequence of float32 (J, 3, 4)
        palettes (or an array (F, J, 3, 4)), all checked before the first is sent. A crowd
        frame is a (K, J, 3, 4) palette (an array (F, K, J, 3, 4) for F of them) and yields
        (K, V, 3) arrays.

        A frame answered NOT_FOUND re-uploads the mesh and the stream resumes from that
        frame; a stream that ends UNAVAILABLE (a replica draining or gone) resumes on a new
        stream (up to max_reconnects times); any other failed frame raises SkinserveError.

        region: a registered SharedMemoryRegion large enough for `window` frames: frame i is
        written into slot i % window and yielded as arrays that view it, valid until the
        next frame is taken (copy what you keep).
        """
        palettes = list(palettes)
        joints = self._joint_count(mesh_id)
        crowds = [_arrays.check_palette(f"palettes[{i}]", palette, joints)
                  for i, palette in enumerate(palettes)]
        if window < 1:
            raise ValueError(f"window: {window}, expected >= 1")
        stride = 0
        if region is not None:
            stride = max((self._frame_bytes(mesh_id, k, want_normals, encoding)
                          for k in set(crowds)), default=0)
            if window * stride > region.byte_size:
                raise ValueError(f"region: {region.byte_size} bytes, fewer than {window} frames "
                                 f"in flight of {stride} bytes")
        requests = [self._request(mesh_id, p, k, i, backend, want_normals, encoding, region,
                                  (i % window) * stride)
                    for i, (p, k) in enumerate(zip(palettes, crowds))]
        next_frame, reuploads, reconnects = 0, 0, 0
        while next_frame < len(requests):
            restart, ended = None, []
            with contextlib.closing(self._one_stream(requests, next_frame, window,
                                                     want_normals, region, ended)) as answers:
                for index, frame in answers:
                    if frame.error is None:
                        next_frame = index + 1
                        yield frame.result(want_normals)
                        continue
                    code, message = frame.error
                    error = SkinserveError(code, message, index)
                    if code != grpc.StatusCode.NOT_FOUND or reuploads >= self.max_reuploads:
                        raise error
                    restart = error
                    break
            if restart is not None:  # resume from the frame that was NOT_FOUND
                reuploads += 1
                self._reupload(mesh_id, restart)
            elif next_frame < len(requests):  # the stream ended UNAVAILABLE or idle early
                reconnects += 1
                if reconnects > self.max_reconnects:
                    code, message = ended[0] if ended else (grpc.StatusCode.UNAVAILABLE, "")
                    raise SkinserveError(code, f"stream ended {reconnects} times, the last: "
                                         f"{message}", next_frame)

    def _one_stream(self, requests, first, window, want_normals, region=None, ended=None):
        """Sends requests[first:] with at most `window` unanswered; yields (index, _Frame)
        in order. Ends early (without raising, the reason appended to `ended`) when the
        stream ends UNAVAILABLE or waits stream_idle_timeout for an answer. With a region, a
        frame's slot is reused only once the caller has taken the next frame."""
        credits = threading.Semaphore(window)
        stop = threading.Event()
        outbox = queue.Queue()
        lock, in_flight = threading.Lock(), [0]
        watchdog = None

        def send():
            for request in requests[first:]:
                while not credits.acquire(timeout=0.1):
                    if stop.is_set():
                        return
                if stop.is_set():
                    return
                outbox.put(request)
            outbox.put(None)

        def request_iterator():
            while True:
                request = outbox.get()
                if request is None:
                    return
                with lock:
                    in_flight[0] += 1
                    watchdog.awaiting(True)
                yield request

        call = self._stub.StreamSkin(request_iterator())
        watchdog = _IdleWatchdog(call, self.stream_idle_timeout)
        sender = threading.Thread(target=send, daemon=True)
        sender.start()

        def new_frame(i):  # the frame answering requests[i]; past the end, one never filled
            return _Frame((requests[i].instances or None) if i < len(requests) else None)

        frame, index = new_frame(first), first
        try:
            for part in call:
                watchdog.answered()
                self._add(frame, part, want_normals, region)
                if part.last:
                    with lock:
                        in_flight[0] -= 1
                    if region is None:
                        credits.release()
                    watchdog.awaiting(False)  # the caller holds the frame: nothing is read
                    yield index, frame
                    with lock:
                        watchdog.awaiting(in_flight[0] > 0)
                    if region is not None:  # the caller is done with the frame's slot
                        credits.release()
                    index += 1
                    frame = new_frame(index)
        except grpc.RpcError as e:
            if watchdog.fired:
                if ended is not None:
                    ended.append((grpc.StatusCode.DEADLINE_EXCEEDED,
                                  f"no answer for {self.stream_idle_timeout} s with frames in "
                                  "flight (stream_idle_timeout)"))
            elif e.code() == grpc.StatusCode.UNAVAILABLE:
                if ended is not None:
                    ended.append((e.code(), e.details()))
            else:
                raise _rpc_error(e, index) from None
        finally:
            watchdog.stop()
            stop.set()
            outbox.put(None)
            call.cancel()
            sender.join()

    # ---- the server ----------------------------------------------------------------------
    def backends(self):
        """The server's backends: a list of dicts (id, description, available, ...)."""
        try:
            response = self._stub.ListBackends(pb.ListBackendsRequest(), timeout=self.timeout)
        except grpc.RpcError as e:
            raise _rpc_error(e) from None
        return [{"id": b.id, "description": b.description, "available": b.available,
                 "unavailable_reason": b.unavailable_reason, "device": b.device,
                 "simd_width": b.simd_width, "threads": b.threads,
                 "default": b.id == response.default_backend} for b in response.backends]

    def stats(self):
        """The server's counters: a dict, with "backends" a dict by backend id."""
        try:
            s = self._stub.GetServerStats(pb.GetServerStatsRequest(), timeout=self.timeout)
        except grpc.RpcError as e:
            raise _rpc_error(e) from None
        out = {f: getattr(s, f) for f in (
            "queue_depth", "queue_capacity", "compute_threads", "meshes", "mesh_bytes",
            "mesh_budget_bytes", "evictions", "rejected_queue_full", "open_streams",
            "regions", "region_bytes", "region_budget_bytes", "region_frames",
            "rejected_regions")}
        out["backends"] = {b.id: {"frames": b.frames, "vertices": b.vertices,
                                  "errors": b.errors, "compute_ns_total": b.compute_ns_total}
                           for b in s.backends}
        return out
