"""Tangents (glTF TANGENT) on upload through a real server: a mesh with tangents stores
under its own content id (tangents are content) and still skins as the float64 reference
written here says (tangents do not come back on the wire yet); bad tangents are refused
on the client (shape, missing normals) or by the server naming the vertex and the limit;
the backend list says which backends skin tangents; morph targets' tangent deltas
(MorphTarget.tangents) upload with their targets and are checked where they land."""
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


def tangent_targets(rng, vertices, count, tangents=True):
    """Targets moving every 4th vertex from a random start, with normal and tangent deltas."""
    targets = []
    for k in range(count):
        indices = np.arange(k, vertices, 4, dtype=np.uint32)
        deltas = [rng.uniform(-0.1, 0.1, size=(len(indices), 3)).astype(np.float32)
                  for _ in range(3)]
        targets.append(skinserve.MorphTarget(indices, deltas[0], deltas[1],
                                             deltas[2] if tangents else None))
    return targets


def test_morph_tangent_deltas_are_uploaded_with_their_targets(client, rng):
    positions, joint_ids, weights, normals = random_mesh(rng, 200, 2, 6)
    tangents = random_tangents(rng, normals)
    targets = tangent_targets(rng, 200, 3)
    with_deltas = client.upload(positions, joint_ids, weights, normals=normals,
                                tangents=tangents, morph_targets=targets)
    without = client.upload(positions, joint_ids, weights, normals=normals, tangents=tangents,
                            morph_targets=[t._replace(tangents=None) for t in targets])
    assert with_deltas != without  # the deltas are content: they reached the server
    # The server checks each delta where it lands: target 1's delta 4 (vertex 17), y.
    targets[1].tangents[4, 1] = 5.0
    with pytest.raises(skinserve.SkinserveError,
                       match=r"morph_tangent_deltas\[target 1, delta 4\]\.y = 5 must be "
                             r"finite and within \+-4"):
        client.upload(positions, joint_ids, weights, normals=normals, tangents=tangents,
                      morph_targets=targets)


def test_bad_morph_tangent_deltas_are_refused_on_the_client(client, rng):
    positions, joint_ids, weights, normals = random_mesh(rng, 40, 2, 4)
    tangents = random_tangents(rng, normals)
    targets = tangent_targets(rng, 40, 2)
    with pytest.raises(ValueError, match="tangent deltas, but the mesh has no tangents"):
        client.upload(positions, joint_ids, weights, normals=normals, morph_targets=targets)
    mixed = [targets[0], targets[1]._replace(tangents=None)]
    with pytest.raises(ValueError, match="some targets have tangent deltas and some not"):
        client.upload(positions, joint_ids, weights, normals=normals, tangents=tangents,
                      morph_targets=mixed)
    short = [targets[0]._replace(tangents=targets[0].tangents[:3])]
    with pytest.raises(ValueError, match=r"morph_targets\[0\]\.tangents: shape \(3, 3\), "
                                         r"expected \(10, 3\)"):
        client.upload(positions, joint_ids, weights, normals=normals, tangents=tangents,
                      morph_targets=short)
