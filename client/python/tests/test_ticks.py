"""Ticks (SkinRequest.characters) from Python against a real server: many characters in one
request, blocking and asyncio, unary and streamed, into shared memory too; every character
against the float64 reference of its own mesh and palette, and a bad character failing alone."""
import asyncio

import grpc
import numpy as np
import pytest

import skinserve
from conftest import Server
from reference import random_mesh, random_palette, skin
from skinserve.v1 import skinning_pb2 as pb
from test_crowds_and_encodings import POSITION_TOLERANCE, check_crowd, check_instance

JOINTS = 30


def crowd_of(rng, k):
    return np.stack([random_palette(rng, JOINTS) for _ in range(k)])


def make_tick(rng, mesh_ids, meshes):
    """A tick mixing shapes: a single palette in float32, a crowd of 3 with normals in
    snorm16, a single palette with normals in float16 on another backend."""
    shapes = [dict(backend="simd"),
              dict(backend="serial", want_normals=True, encoding="snorm16", crowd=3),
              dict(backend="sse", want_normals=True, encoding="float16")]
    characters = []
    for i, shape in enumerate(shapes):
        crowd = shape.pop("crowd", None)
        palette = crowd_of(rng, crowd) if crowd else random_palette(rng, JOINTS)
        characters.append(skinserve.Character(mesh_ids[i % len(mesh_ids)], palette, **shape))
    return characters


def check_result(result, character, mesh):
    """A character's answer against the float64 reference of its mesh and palette(s)."""
    assert result.ok, result.error
    palettes = character.palette if character.palette.ndim == 4 else character.palette[None]
    positions = result.positions if character.palette.ndim == 4 else result.positions[None]
    if character.want_normals:
        normals = result.normals if character.palette.ndim == 4 else result.normals[None]
        check_crowd(positions.astype(np.float32), normals.astype(np.float32), mesh, palettes,
                    character.encoding)
    else:
        assert result.normals is None
        for k, palette in enumerate(palettes):
            check_instance(positions[k].astype(np.float32), skin(*mesh, palette)[0],
                           character.encoding, POSITION_TOLERANCE)


@pytest.fixture
def meshes(rng):
    return [random_mesh(rng, n, b, JOINTS) for n, b in ((1500, 2), (2200, 3), (900, 4))]


def test_tick_answers_every_character_against_its_own_reference(client, rng, meshes):
    mesh_ids = [client.upload(*m) for m in meshes]
    assert len(set(mesh_ids)) == 3
    characters = make_tick(rng, mesh_ids, meshes)
    results = client.tick(characters, frame=5)
    assert [r.index for r in results] == [0, 1, 2]
    assert results[1].positions.shape == (3, 2200, 3)  # the crowd: (K, V, 3)
    assert results[0].positions.shape == (1500, 3)
    for result, character, mesh in zip(results, characters, meshes):
        check_result(result, character, mesh)
        assert result.timing["compute_ns"] > 0


def test_a_bad_character_fails_alone_and_is_named(client, rng, meshes):
    mesh_ids = [client.upload(*m) for m in meshes]
    characters = make_tick(rng, mesh_ids, meshes)
    characters[1].backend = "no-such-backend"
    results = client.tick(characters)
    assert results[1].error is not None
    assert results[1].error.code == grpc.StatusCode.INVALID_ARGUMENT
    assert "no-such-backend" in results[1].error.message, results[1].error.message
    assert results[1].positions is None
    for i in (0, 2):
        check_result(results[i], characters[i], meshes[i])
    # A mesh the server does not have and this client never uploaded: NOT_FOUND, alone.
    unknown = skinserve.Character("0" * 64, random_palette(rng, JOINTS))
    results = client.tick([characters[0], unknown])
    assert results[1].error.code == grpc.StatusCode.NOT_FOUND
    check_result(results[0], characters[0], meshes[0])


def test_a_character_whose_mesh_went_is_uploaded_again(client, rng, meshes):
    mesh_ids = [client.upload(*m) for m in meshes[:2]]
    client._stub.DeleteMesh(pb.DeleteMeshRequest(mesh_id=mesh_ids[1]), timeout=10)
    characters = [skinserve.Character(mesh_ids[0], random_palette(rng, JOINTS)),
                  skinserve.Character(mesh_ids[1], random_palette(rng, JOINTS))]
    results = client.tick(characters)
    for result, character, mesh in zip(results, characters, meshes):
        check_result(result, character, mesh)


def test_bad_characters_are_refused_before_sending(client, rng, meshes):
    mesh_id = client.upload(*meshes[0])
    with pytest.raises(ValueError, match="characters: empty"):
        client.tick([])
    with pytest.raises(ValueError, match=r"characters\[0\].palette"):
        client.tick([skinserve.Character(mesh_id, random_palette(rng, JOINTS + 1))])
    with pytest.raises(ValueError, match="encoding"):
        client.tick([skinserve.Character(mesh_id, random_palette(rng, JOINTS), encoding="x")])


def test_stream_of_ticks_yields_each_tick_in_order(client, rng, meshes):
    mesh_ids = [client.upload(*m) for m in meshes]
    ticks = [make_tick(rng, mesh_ids, meshes) for _ in range(5)]
    ticks[3][2].backend = "no-such-backend"  # fails alone, the stream goes on
    answered = list(client.stream_ticks(ticks, window=2))
    assert len(answered) == 5
    for t, (results, characters) in enumerate(zip(answered, ticks)):
        for i, (result, character) in enumerate(zip(results, characters)):
            if (t, i) == (3, 2):
                assert result.error.code == grpc.StatusCode.INVALID_ARGUMENT
            else:
                check_result(result, character, meshes[i])


def test_asyncio_tick_and_stream_of_ticks(server, rng, meshes):
    async def main():
        async with skinserve.AsyncClient(server.target) as client:
            mesh_ids = [await client.upload(*m) for m in meshes]
            characters = make_tick(rng, mesh_ids, meshes)
            characters.append(skinserve.Character(mesh_ids[0], random_palette(rng, JOINTS),
                                                  backend="no-such-backend"))
            results = await client.tick(characters, frame=2)
            for result, character, mesh in zip(results[:3], characters, meshes):
                check_result(result, character, mesh)
            assert results[3].error.code == grpc.StatusCode.INVALID_ARGUMENT
            ticks = [make_tick(rng, mesh_ids, meshes) for _ in range(4)]
            streamed = [r async for r in client.stream_ticks(ticks, window=3)]
            assert len(streamed) == 4
            for results, characters in zip(streamed, ticks):
                for result, character, mesh in zip(results, characters, meshes):
                    check_result(result, character, mesh)
    asyncio.run(asyncio.wait_for(main(), timeout=120))


@pytest.fixture(scope="module")
def shm_server(binary, shm_dir):
    s = Server(binary, "--shm-dir", shm_dir, unix_socket=True)
    yield s
    s.stop()


def test_ticks_into_shared_memory_each_character_its_range(shm_server, shm_dir, rng, meshes):
    with skinserve.Client(shm_server.unix_target) as client, \
            skinserve.SharedMemoryRegion(8 << 20, directory=shm_dir) as region:
        client.register_region(region)
        mesh_ids = [client.upload(*m) for m in meshes]
        characters = make_tick(rng, mesh_ids, meshes)
        offset = 0
        for c in characters:  # each character its own range, one after another
            c.region, c.offset = region, offset
            offset += 1 << 20
        results = client.tick(characters)
        for result, character, mesh in zip(results, characters, meshes):
            check_result(result, character, mesh)
        ticks = [make_tick(rng, mesh_ids, meshes) for _ in range(3)]
        for t in ticks:
            for i, c in enumerate(t):
                c.region, c.offset = region, i << 20
        for results, characters in zip(client.stream_ticks(ticks, window=2), ticks):
            for result, character, mesh in zip(results, characters, meshes):
                check_result(result, character, mesh)
        client.unregister_region(region)
