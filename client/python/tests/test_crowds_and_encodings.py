"""Encodings and crowd batches through a real server, every answer against the float64
reference within float32's tolerance plus the bound of the encoding used."""
import grpc
import numpy as np
import pytest

import skinserve
from reference import random_mesh, random_palette, skin

JOINTS = 30
# float32's own rounding, tighter than reference.py's: |M p| <= ~4.3 here, so a few ulp is
# ~2e-6. Kept below snorm16's half step on these meshes (~6e-5), so a wrong bound shows.
POSITION_TOLERANCE = 1e-5
NORMAL_TOLERANCE = 5e-6  # float32 normals were seen 2.6e-6 off (60k vertices, sse)
ENCODINGS = ["float32", "float16", "snorm16"]


def encoding_bound(encoding, want, normals=False):
    """Per value, how far a decoded answer may lie from the exact result beyond float32's
    rounding (docs/serving/encodings.md)."""
    if encoding == "float32":
        return np.zeros_like(want)
    if encoding == "float16":
        return np.maximum(np.abs(want) * 2.0 ** -11, 2.0 ** -25)
    if normals:
        return np.full_like(want, 1 / 65534 + 2.0 ** -24)
    extent = want.max(axis=0) - want.min(axis=0)  # the instance's box, per axis
    return np.broadcast_to(extent / 131068 + 2.0 ** -20 * np.abs(want).max(axis=0), want.shape)


def check_instance(got, want, encoding, tolerance, normals=False):
    assert got.dtype == np.float32 and got.shape == want.shape
    excess = np.abs(got.astype(np.float64) - want) - encoding_bound(encoding, want, normals)
    assert np.all(excess <= tolerance), (encoding, float(np.max(excess)))  # NaN fails


def check_crowd(got_p, got_n, mesh, palettes, encoding):
    assert got_p.shape[0] == len(palettes)
    for k, palette in enumerate(palettes):
        want_p, want_n = skin(*mesh, palette)
        check_instance(got_p[k], want_p, encoding, POSITION_TOLERANCE)
        check_instance(got_n[k], want_n, encoding, NORMAL_TOLERANCE, normals=True)


def test_backends_list_the_encodings_they_write_themselves(client):
    """BackendInfo.encoded_outputs: the OpenCL backends encode float16 and snorm16 on the
    device, the simd loops as they skin; the other CPU backends leave encoding to the server."""
    listed = {b["id"]: b for b in client.backends()}
    for backend in ("opencl", "opencl-zerocopy"):
        if not listed[backend]["available"]:
            pytest.skip(f"{backend} unavailable: {listed[backend]['unavailable_reason']}")
        assert listed[backend]["encoded_outputs"] == ["float16", "snorm16"], backend
        assert listed[backend]["quantized_rest"], backend
    for backend in ("simd", "simd-openmp"):
        assert listed[backend]["encoded_outputs"] == ["float16", "snorm16"], backend
    for backend in ("serial", "sse", "passthrough"):
        assert listed[backend]["encoded_outputs"] == [], backend


@pytest.mark.parametrize("encoding", ENCODINGS)
def test_every_encoding_and_crowd_size_on_every_backend(client, rng, encoding):
    mesh = random_mesh(rng, 1500, 3, JOINTS)
    mesh_id = client.upload(*mesh)
    backends = [b["id"] for b in client.backends()
                if b["available"] and b["id"] != "passthrough"]
    for backend in backends:
        single = random_palette(rng, JOINTS)
        p, n = client.skin(mesh_id, single, backend=backend, want_normals=True,
                           encoding=encoding)
        assert p.shape == (1500, 3)  # a single palette answers one vertex set
        check_crowd(p[None], n[None], mesh, [single], encoding)
        for k in (1, 3):
            crowd = np.stack([random_palette(rng, JOINTS) for _ in range(k)])
            p, n = client.skin(mesh_id, crowd, backend=backend, want_normals=True,
                               encoding=encoding)
            assert p.shape == (k, 1500, 3), backend  # a crowd of 1 keeps its K axis
            check_crowd(p, n, mesh, crowd, encoding)


def test_crowd_instances_span_several_parts(client, rng):
    # 60k vertices with normals: 1.44 MB per instance in float32, two 1 MiB parts each.
    mesh = random_mesh(rng, 60_000, 2, JOINTS)
    mesh_id = client.upload(*mesh)
    crowd = np.stack([random_palette(rng, JOINTS) for _ in range(3)])
    for encoding in ("float32", "snorm16"):
        p, n = client.skin(mesh_id, crowd, backend="sse", want_normals=True, encoding=encoding)
        check_crowd(p, n, mesh, crowd, encoding)


def test_stream_mixes_crowds_and_single_palettes(client, rng):
    mesh = random_mesh(rng, 2000, 2, JOINTS)
    mesh_id = client.upload(*mesh)
    sizes = [None, 2, 5, None, 1, 3]
    palettes = [random_palette(rng, JOINTS) if k is None else
                np.stack([random_palette(rng, JOINTS) for _ in range(k)]) for k in sizes]
    frames = list(client.stream(mesh_id, palettes, backend="sse", want_normals=True,
                                encoding="snorm16", window=3))
    assert len(frames) == len(sizes)
    for k, palette, (p, n) in zip(sizes, palettes, frames):
        if k is None:
            check_crowd(p[None], n[None], mesh, [palette], "snorm16")
        else:
            check_crowd(p, n, mesh, palette, "snorm16")


def test_a_bad_instance_is_named_and_harms_nothing_else(client, rng):
    mesh = random_mesh(rng, 800, 2, JOINTS)
    mesh_id = client.upload(*mesh)
    good = np.stack([random_palette(rng, JOINTS) for _ in range(4)])
    bad = good.copy()
    bad[2, 5, 0, 3] = np.nan  # instance 2 of 4, in the middle of the batch
    palettes = [good, bad, good]
    answers = client.stream(mesh_id, palettes, backend="serial", want_normals=True)
    p, n = next(answers)  # the frame before the bad one is answered in full
    check_crowd(p, n, mesh, good, "float32")
    with pytest.raises(skinserve.SkinserveError) as e:
        next(answers)
    assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT and e.value.frame == 1
    assert "instance 2" in e.value.message
    # The same client and mesh carry on.
    p, n = client.skin(mesh_id, good, backend="serial", want_normals=True)
    check_crowd(p, n, mesh, good, "float32")


def test_crowd_over_the_servers_limit_is_refused(client, rng):
    mesh_id = client.upload(*random_mesh(rng, 100, 1, JOINTS))
    crowd = np.stack([random_palette(rng, JOINTS)] * 65)
    with pytest.raises(skinserve.SkinserveError) as e:
        client.skin(mesh_id, crowd, backend="serial")
    assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT
    assert "instances = 65 exceeds the limit of 64" in e.value.message
