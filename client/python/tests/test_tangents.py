"""Tangents (glTF TANGENT) on upload through a real server: a mesh with tangents stores
under its own content id (tangents are content) and still skins as the float64 reference
written here says (tangents do not come back on the wire yet); bad tangents are refused
on the client (shape, missing normals) or by the server naming the vertex and the limit;
the backend list says which backends skin tangents."""
import numpy as np
import pytest

import skinserve
from reference import random_mesh, random_palette, skin

TOLERANCE = 2e-5


def random_tangents(rng, normals):
    """Unit vectors perpendicular to the normals, w +1 or -1."""
    t = np.cross(normals.astype(np.float64), rng.normal(size=normals.shape))
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    w = np.where(rng.uniform(size=(len(t), 1)) < 0.5, -1.0, 1.0)
    return np.hstack([t, w]).astype(np.float32)


def test_a_mesh_with_tangents_is_its_own_content_and_skins_as_before(client, rng):
    positions, joint_ids, weights, normals = random_mesh(rng, 300, 3, 12)
    tangents = random_tangents(rng, normals)
    with_id = client.upload(positions, joint_ids, weights, normals=normals, tangents=tangents)
    without_id = client.upload(positions, joint_ids, weights, normals=normals)
    assert with_id != without_id
    palette = random_palette(rng, 12)
    got_p, got_n = client.skin(with_id, palette, want_normals=True)
    want_p, want_n = skin(positions.astype(np.float64), joint_ids, weights,
                          normals.astype(np.float64), palette)
    assert float(np.max(np.abs(got_p - want_p))) <= TOLERANCE
    assert float(np.max(np.abs(got_n - want_n))) <= TOLERANCE


def test_bad_tangents_are_refused_naming_the_field(client, rng):
    positions, joint_ids, weights, normals = random_mesh(rng, 50, 2, 4)
    tangents = random_tangents(rng, normals)
    with pytest.raises(ValueError, match=r"tangents: shape \(50, 3\), expected \(50, 4\)"):
        client.upload(positions, joint_ids, weights, normals=normals, tangents=tangents[:, :3])
    with pytest.raises(ValueError, match="tangents need normals"):
        client.upload(positions, joint_ids, weights, tangents=tangents)
    tangents[7, 3] = 0.5
    with pytest.raises(skinserve.SkinserveError,
                       match=r"tangents\[vertex 7\]\.w = 0.5; it must be exactly \+1 or -1"):
        client.upload(positions, joint_ids, weights, normals=normals, tangents=tangents)


def test_backends_say_which_skin_tangents(client):
    backends = {b["id"]: b for b in client.backends()}
    assert backends["simd"]["tangents"] and backends["serial"]["tangents"]
    # Every backend that runs here skins them, the OpenCL ones on the device too.
    for backend in backends.values():
        assert backend["tangents"] == backend["available"], backend["id"]
