"""Tangents (glTF TANGENT) through a real server: a mesh with tangents stores under its own
content id (tangents are content) and skins as the float64 reference written here says;
want_tangents answers them in every encoding, single and crowd, over gRPC and in a
shared-memory region, from the blocking and the asyncio client, x y z within float32's
rounding plus the encoding's bound and w exactly +1 / -1; asking where tangents cannot
come is refused naming want_tangents; bad tangents are refused on the client (shape,
missing normals) or by the server naming the vertex and the limit; the backend list says
which backends skin tangents; morph targets' tangent deltas (MorphTarget.tangents) upload
with their targets and are checked where they land."""
import asyncio

import grpc
import numpy as np
import pytest

import skinserve
from conftest import Server
from reference import random_mesh, random_palette, skin
from test_crowds_and_encodings import ENCODINGS, NORMAL_TOLERANCE, POSITION_TOLERANCE, \
    check_instance

TOLERANCE = 2e-5
JOINTS = 12


def random_tangents(rng, normals):
    """Unit vectors perpendicular to the normals, w +1 or -1."""
    t = np.cross(normals.astype(np.float64), rng.normal(size=normals.shape))
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    w = np.where(rng.uniform(size=(len(t), 1)) < 0.5, -1.0, 1.0)
    return np.hstack([t, w]).astype(np.float32)


def skin_tangents(tangents, joint_ids, weights, palette):
    """Float64 reference: t' = normalise(sum_i w_i R_i t.xyz), w copied (R_i: M_i's 3x3)."""
    m = np.einsum("vi,virc->vrc", weights.astype(np.float64),
                  palette.astype(np.float64)[joint_ids])
    t = np.einsum("vrc,vc->vr", m[:, :, :3], tangents[:, :3].astype(np.float64))
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    return np.hstack([t, tangents[:, 3:].astype(np.float64)])


def check_tangents(got, want, encoding):
    """x y z as normals are checked; w exactly the rest's +1 or -1."""
    assert got.dtype == np.float32 and got.shape == want.shape
    check_instance(got[:, :3], want[:, :3], encoding, NORMAL_TOLERANCE, normals=True)
    assert np.array_equal(got[:, 3], want[:, 3]), encoding
    assert set(np.unique(got[:, 3])) <= {-1.0, 1.0}


def tangent_mesh(rng, vertices=300):
    positions, joint_ids, weights, normals = random_mesh(rng, vertices, 3, JOINTS)
    return positions, joint_ids, weights, normals, random_tangents(rng, normals)


def check_answer(answer, mesh, palettes, encoding):
    positions, joint_ids, weights, normals, tangents = mesh
    got_p, got_n, got_t = answer
    for k, palette in enumerate(palettes):
        want_p, want_n = skin(positions, joint_ids, weights, normals, palette)
        check_instance(got_p[k], want_p, encoding, POSITION_TOLERANCE)
        check_instance(got_n[k], want_n, encoding, NORMAL_TOLERANCE, normals=True)
        check_tangents(got_t[k], skin_tangents(tangents, joint_ids, weights, palette), encoding)


@pytest.mark.parametrize("encoding", ENCODINGS)
def test_tangents_come_back_in_every_encoding_single_and_crowd(client, rng, encoding):
    mesh = tangent_mesh(rng)
    positions, joint_ids, weights, normals, tangents = mesh
    mesh_id = client.upload(positions, joint_ids, weights, normals=normals, tangents=tangents)
    single = random_palette(rng, JOINTS)
    p, n, t = client.skin(mesh_id, single, want_normals=True, want_tangents=True,
                          encoding=encoding)
    assert p.shape == (300, 3) and n.shape == (300, 3) and t.shape == (300, 4)
    check_answer((p[None], n[None], t[None]), mesh, [single], encoding)
    crowd = np.stack([random_palette(rng, JOINTS) for _ in range(3)])
    answer = client.skin(mesh_id, crowd, want_normals=True, want_tangents=True,
                         encoding=encoding)
    assert answer[2].shape == (3, 300, 4)
    check_answer(answer, mesh, crowd, encoding)
    frames = list(client.stream(mesh_id, [single, crowd], want_normals=True,
                                want_tangents=True, encoding=encoding, window=2))
    check_answer(tuple(a[None] for a in frames[0]), mesh, [single], encoding)
    check_answer(frames[1], mesh, crowd, encoding)


def test_the_asyncio_client_answers_tangents(server, rng):
    mesh = tangent_mesh(rng)
    positions, joint_ids, weights, normals, tangents = mesh
    crowd = np.stack([random_palette(rng, JOINTS) for _ in range(2)])

    async def main():
        async with skinserve.AsyncClient(server.target) as c:
            mesh_id = await c.upload(positions, joint_ids, weights, normals=normals,
                                     tangents=tangents)
            one = await c.skin(mesh_id, crowd, want_normals=True, want_tangents=True,
                               encoding="float16")
            streamed = [a async for a in c.stream(mesh_id, [crowd], want_normals=True,
                                                  want_tangents=True, encoding="snorm16")]
            return one, streamed

    one, streamed = asyncio.run(asyncio.wait_for(main(), timeout=120))
    check_answer(one, mesh, crowd, "float16")
    check_answer(streamed[0], mesh, crowd, "snorm16")


def as_float32(answer):
    """A region's float16 answer views the region as float16: widen it (exactly)."""
    return tuple(np.asarray(a, dtype=np.float32) for a in answer)


@pytest.fixture(scope="module")
def shm_client(binary, shm_dir):
    s = Server(binary, "--shm-dir", shm_dir, unix_socket=True)
    with skinserve.Client(s.unix_target) as c:
        yield c
    s.stop()


@pytest.mark.parametrize("encoding", ENCODINGS)
def test_tangents_land_in_a_region_after_the_normals(shm_client, shm_dir, rng, encoding):
    mesh = tangent_mesh(rng)
    positions, joint_ids, weights, normals, tangents = mesh
    mesh_id = shm_client.upload(positions, joint_ids, weights, normals=normals,
                                tangents=tangents)
    crowd = np.stack([random_palette(rng, JOINTS) for _ in range(2)])
    with skinserve.SharedMemoryRegion(1 << 20, directory=shm_dir) as region:
        shm_client.register_region(region)
        answer = shm_client.skin(mesh_id, crowd, want_normals=True, want_tangents=True,
                                 encoding=encoding, region=region, offset=64)
        assert answer[2].shape == (2, 300, 4)
        check_answer(as_float32(answer), mesh, crowd, encoding)
        frames = list(shm_client.stream(mesh_id, [crowd, crowd], want_normals=True,
                                        want_tangents=True, encoding=encoding, region=region,
                                        window=2))
        for frame in frames:
            check_answer(as_float32(frame), mesh, crowd, encoding)
        shm_client.unregister_region(region)


def test_asking_for_tangents_where_none_can_come_names_want_tangents(client, rng):
    positions, joint_ids, weights, normals, tangents = tangent_mesh(rng, 50)
    plain = client.upload(positions, joint_ids, weights, normals=normals)
    palette = random_palette(rng, JOINTS)
    with pytest.raises(skinserve.SkinserveError, match="want_tangents is set but mesh .* has no "
                       "tangents") as e:
        client.skin(plain, palette, want_normals=True, want_tangents=True)
    assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT
    with_id = client.upload(positions, joint_ids, weights, normals=normals, tangents=tangents)
    with pytest.raises(skinserve.SkinserveError, match="want_tangents is set without "
                       "want_normals"):
        client.skin(with_id, palette, want_tangents=True)  # type: ignore[call-overload]
    for backend in client.backends():
        if backend["available"] and not backend["tangents"]:
            with pytest.raises(skinserve.SkinserveError,
                               match=f"want_tangents is set but backend '{backend['id']}'") as e:
                client.skin(with_id, palette, backend=backend["id"], want_normals=True,
                            want_tangents=True)
            assert e.value.code == grpc.StatusCode.FAILED_PRECONDITION


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
