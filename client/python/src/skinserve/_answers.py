"""The server's answers about itself (backends, counters, regions) as plain dicts, for
both clients."""
from typing import Any, Dict, List

from ._requests import ENCODINGS
from .v1 import skinning_pb2 as pb

ENCODING_NAMES = {value: name for name, value in ENCODINGS.items()}


def backends(response: pb.ListBackendsResponse) -> List[Dict[str, Any]]:
    """encoded_outputs: the encodings the backend writes itself ("float16", "snorm16" on the
    OpenCL backends: encoded on the device); the server encodes the others."""
    return [{"id": b.id, "description": b.description, "available": b.available,
             "unavailable_reason": b.unavailable_reason, "device": b.device,
             "simd_width": b.simd_width, "threads": b.threads,
             "morph_targets": b.morph_targets, "tangents": b.tangents,
             "quantized_rest": b.quantized_rest,
             "encoded_outputs": [ENCODING_NAMES.get(e, str(e)) for e in b.encoded_outputs],
             "default": b.id == response.default_backend} for b in response.backends]


def stats(s: pb.ServerStats) -> Dict[str, Any]:
    out: Dict[str, Any] = {f: getattr(s, f) for f in (
        "queue_depth", "queue_capacity", "compute_threads", "meshes", "mesh_bytes",
        "mesh_budget_bytes", "evictions", "rejected_queue_full", "open_streams",
        "regions", "region_bytes", "region_budget_bytes", "region_frames",
        "rejected_regions", "skeletons", "clips", "clip_bytes", "clip_budget_bytes")}
    out["backends"] = {b.id: {"frames": b.frames, "vertices": b.vertices,
                              "errors": b.errors, "compute_ns_total": b.compute_ns_total}
                       for b in s.backends}
    return out


def regions(response: pb.ListRegionsResponse) -> List[Dict[str, Any]]:
    return [{"name": r.name, "key": r.key, "byte_size": r.byte_size,
             "frames_written": r.frames_written, "idle_seconds": r.idle_seconds}
            for r in response.regions]
