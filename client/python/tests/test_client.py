"""The Python client against a real skinserve server, every answer against float64."""
import grpc
import numpy as np
import pytest

import skinserve
from reference import (NORMAL_TOLERANCE, POSITION_TOLERANCE, max_error, random_mesh,
                       random_palette, skin)

JOINTS = 40


def computing_backends(client):
    return [b["id"] for b in client.backends() if b["available"] and b["id"] != "passthrough"]


def test_backends_and_stats(client):
    backends = client.backends()
    ids = [b["id"] for b in backends]
    assert "serial" in ids and "sse" in ids
    assert sum(b["default"] for b in backends) == 1
    stats = client.stats()
    assert stats["compute_threads"] == 1
    assert set(stats["backends"]) == set(ids)


def test_skin_every_backend_matches_float64(client, rng):
    mesh = random_mesh(rng, 3001, 3, JOINTS)
    mesh_id = client.upload(*mesh)
    for backend in computing_backends(client):
        palette = random_palette(rng, JOINTS)
        positions, normals = client.skin(mesh_id, palette, backend=backend, want_normals=True)
        want_p, want_n = skin(*mesh, palette)
        assert positions.shape == (3001, 3) and positions.dtype == np.float32
        assert max_error(positions, want_p) <= POSITION_TOLERANCE, backend
        assert max_error(normals, want_n) <= NORMAL_TOLERANCE, backend


def test_large_frame_arrives_in_parts(client, rng):
    # 200k vertices with normals: 4.8 MB, several 1 MiB response parts.
    mesh = random_mesh(rng, 200_000, 2, JOINTS)
    mesh_id = client.upload(*mesh)
    palette = random_palette(rng, JOINTS)
    positions, normals = client.skin(mesh_id, palette, backend="sse", want_normals=True)
    want_p, want_n = skin(*mesh, palette)
    assert max_error(positions, want_p) <= POSITION_TOLERANCE
    assert max_error(normals, want_n) <= NORMAL_TOLERANCE


def test_stream_in_order_matches_float64(client, rng):
    positions, joints, weights, _ = random_mesh(rng, 2000, 4, JOINTS)
    mesh_id = client.upload(positions, joints, weights)
    palettes = np.stack([random_palette(rng, JOINTS) for _ in range(25)])
    frames = list(client.stream(mesh_id, palettes, backend="sse", window=4))
    assert len(frames) == len(palettes)
    for palette, got in zip(palettes, frames):
        want, _ = skin(positions, joints, weights, None, palette)
        assert max_error(got, want) <= POSITION_TOLERANCE


def test_upload_is_deduplicated_by_content(client, rng):
    mesh = random_mesh(rng, 100, 1, JOINTS)
    assert client.upload(*mesh) == client.upload(*mesh)


def test_reupload_after_the_server_lost_the_mesh(client, server, rng):
    # Another client deletes the mesh (as an eviction or another replica would lose it):
    # skin and stream upload it again from what this client remembers, and carry on.
    mesh = random_mesh(rng, 500, 2, JOINTS)
    mesh_id = client.upload(*mesh)
    other = skinserve.Client(server.target)
    palette = random_palette(rng, JOINTS)
    want, _ = skin(*mesh, palette)
    other._stub.DeleteMesh(skinserve._client.pb.DeleteMeshRequest(mesh_id=mesh_id))
    assert max_error(client.skin(mesh_id, palette, backend="serial"), want) <= POSITION_TOLERANCE
    other._stub.DeleteMesh(skinserve._client.pb.DeleteMeshRequest(mesh_id=mesh_id))
    frames = list(client.stream(mesh_id, [palette] * 5, backend="serial"))
    assert len(frames) == 5
    for got in frames:
        assert max_error(got, want) <= POSITION_TOLERANCE
    other.close()


def test_unknown_mesh_raises_with_the_servers_message(client, rng):
    with pytest.raises(skinserve.SkinserveError) as e:
        client.skin("0" * 64, random_palette(rng, JOINTS))
    assert e.value.code == grpc.StatusCode.NOT_FOUND
    assert "0" * 64 in e.value.message  # the server's own message names the mesh


def test_server_errors_carry_code_and_message(client, rng):
    mesh_id = client.upload(*random_mesh(rng, 100, 1, JOINTS))
    with pytest.raises(skinserve.SkinserveError) as e:
        client.skin(mesh_id, random_palette(rng, JOINTS), backend="no-such-backend")
    assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT
    assert "no-such-backend" in str(e.value)
    with pytest.raises(skinserve.SkinserveError) as e:
        list(client.stream(mesh_id, [random_palette(rng, JOINTS)] * 3, backend="no-such"))
    assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT and e.value.frame == 0
    # Weights that do not sum to 1: refused by the server, naming the vertex.
    positions, joints, weights, _ = random_mesh(rng, 10, 2, JOINTS)
    weights[3] *= 2
    with pytest.raises(skinserve.SkinserveError) as e:
        client.upload(positions, joints, weights)
    assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT and "3" in e.value.message
    assert client.upload(positions, joints, weights, normalize_weights=True)


def test_joint_count_beyond_the_ids_used(client, rng):
    # A skin whose palette has joints no vertex uses (common in glTF files).
    mesh = random_mesh(rng, 300, 2, JOINTS)
    mesh_id = client.upload(*mesh, joint_count=JOINTS + 5)
    palette = random_palette(rng, JOINTS + 5)
    want, _ = skin(*mesh, palette)
    assert max_error(client.skin(mesh_id, palette, backend="sse"), want) <= POSITION_TOLERANCE
