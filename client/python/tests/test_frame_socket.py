"""The frame socket from Python (skinserve.FrameSocket and AsyncFrameSocket): regions
registered over gRPC on the server's Unix socket, frames and ticks sent over its
--frame-socket, every answer checked against the float64 reference; a frame's error (or a
tick's character's) leaves the connection going; the server's reason when it ends one."""
import asyncio
import os
import socket
import struct

import grpc
import numpy as np
import pytest

import skinserve
from conftest import Server
from skinserve.v1 import skinning_pb2 as pb
from reference import random_mesh, random_palette, skin
from test_crowds_and_encodings import NORMAL_TOLERANCE, POSITION_TOLERANCE, check_instance
from test_ticks import check_result, make_tick

JOINTS = 30


@pytest.fixture(scope="module")
def socket_server(binary, shm_dir):
    path = os.path.join(shm_dir, "frames.sock")
    s = Server(binary, "--shm-dir", shm_dir, "--frame-socket", path, "--stream-idle-seconds",
               "2", unix_socket=True)
    s.frame_socket = path
    yield s
    s.stop()


@pytest.fixture
def socket_client(socket_server):
    with skinserve.Client(socket_server.unix_target) as c:
        yield c


@pytest.mark.parametrize("encoding", ["float32", "float16", "snorm16"])
def test_frames_over_the_socket_match_the_reference(socket_server, socket_client, shm_dir, rng,
                                                    encoding):
    mesh = random_mesh(rng, 1500, 3, JOINTS)
    mesh_id = socket_client.upload(*mesh)
    with skinserve.SharedMemoryRegion(4 << 20, directory=shm_dir) as region, \
            skinserve.FrameSocket(socket_server.frame_socket, socket_client) as frames:
        socket_client.register_region(region)
        for k in (None, 2):
            palettes = np.stack([random_palette(rng, JOINTS) for _ in range(k or 1)])
            p, n = frames.skin(mesh_id, palettes if k else palettes[0], want_normals=True,
                               encoding=encoding, region=region, offset=64)
            if k is None:
                p, n = p[None], n[None]
            for i, palette in enumerate(palettes):
                want_p, want_n = skin(*mesh, palette)
                check_instance(p[i].astype(np.float32), want_p, encoding, POSITION_TOLERANCE)
                check_instance(n[i].astype(np.float32), want_n, encoding, NORMAL_TOLERANCE,
                               normals=True)
        # Without a region: the vertices come in the answer, as from Client.skin.
        palette = random_palette(rng, JOINTS)
        p = frames.skin(mesh_id, palette, encoding=encoding)
        check_instance(p, skin(*mesh, palette)[0], encoding, POSITION_TOLERANCE)
        socket_client.unregister_region(region)


def test_a_bad_frame_fails_alone_and_a_quiet_connection_ends(socket_server, socket_client, rng):
    mesh = random_mesh(rng, 800, 2, JOINTS)
    mesh_id = socket_client.upload(*mesh)
    with skinserve.FrameSocket(socket_server.frame_socket, socket_client) as frames:
        with pytest.raises(skinserve.SkinserveError) as e:  # the server's check, not ours
            frames.skin(mesh_id, random_palette(rng, JOINTS), frame=3, backend="no-such")
        assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT
        assert "no-such" in e.value.message and e.value.frame == 3
        palette = random_palette(rng, JOINTS)
        p = frames.skin(mesh_id, palette, frame=4)
        check_instance(p, skin(*mesh, palette)[0], "float32", POSITION_TOLERANCE)
        # Nothing sent for --stream-idle-seconds (2 s): the server ends it, naming frame 4.
        with pytest.raises(skinserve.SkinserveError) as e:
            frames._read()  # pylint: disable=protected-access
        assert e.value.code == grpc.StatusCode.UNAVAILABLE
        assert "--stream-idle-seconds" in e.value.message and "frame 4" in e.value.message


def test_a_wrong_greeting_is_refused_naming_the_protocol(socket_server):
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.connect(socket_server.frame_socket)
        s.sendall(b"HELLO!!!")
        data = b""
        while chunk := s.recv(4096):
            data += chunk
    (header,) = struct.unpack("<I", data[:4])
    assert header & 0x80000000
    end = pb.SkinResponse.FromString(data[4:4 + (header & 0x7FFFFFFF)])
    assert end.error.code == grpc.StatusCode.INVALID_ARGUMENT.value[0]
    assert "SKFRAME1" in end.error.message


def test_ticks_over_the_socket_mix_regions_answers_and_a_bad_character(socket_server,
                                                                      socket_client, shm_dir,
                                                                      rng):
    meshes = [random_mesh(rng, n, b, JOINTS) for n, b in ((1500, 2), (2200, 3), (900, 4))]
    mesh_ids = [socket_client.upload(*m) for m in meshes]
    with skinserve.SharedMemoryRegion(8 << 20, directory=shm_dir) as region, \
            skinserve.FrameSocket(socket_server.frame_socket, socket_client) as frames:
        socket_client.register_region(region)
        characters = make_tick(rng, mesh_ids, meshes)
        characters[0].region, characters[0].offset = region, 0  # into the region
        characters[2].region, characters[2].offset = region, 1 << 20
        for frame in (7, 8):  # the same connection, tick after tick
            results = frames.tick(characters, frame=frame)
            assert [r.index for r in results] == [0, 1, 2]
            for result, character, mesh in zip(results, characters, meshes):
                check_result(result, character, mesh)
        # A bad character fails alone, named; the others are answered.
        characters[1].backend = "no-such-backend"
        unknown = skinserve.Character("0" * 64, random_palette(rng, JOINTS))
        results = frames.tick(characters + [unknown])
        assert results[1].error.code == grpc.StatusCode.INVALID_ARGUMENT
        assert "no-such-backend" in results[1].error.message
        assert results[3].error.code == grpc.StatusCode.NOT_FOUND  # no re-upload here
        for i in (0, 2):
            check_result(results[i], characters[i], meshes[i])
        socket_client.unregister_region(region)


def run(coroutine):
    return asyncio.run(asyncio.wait_for(coroutine, timeout=120))


def test_asyncio_frames_and_ticks_over_the_socket(socket_server, shm_dir, rng):
    meshes = [random_mesh(rng, n, b, JOINTS) for n, b in ((1500, 2), (2200, 3), (900, 4))]

    async def main():
        async with skinserve.AsyncClient(socket_server.unix_target) as client:
            mesh_ids = [await client.upload(*m) for m in meshes]
            with skinserve.SharedMemoryRegion(4 << 20, directory=shm_dir) as region:
                await client.register_region(region)
                async with skinserve.AsyncFrameSocket(socket_server.frame_socket,
                                                      client) as frames:
                    palette = random_palette(rng, JOINTS)
                    p, n = await frames.skin(mesh_ids[0], palette, want_normals=True,
                                             region=region, offset=128)
                    want_p, want_n = skin(*meshes[0], palette)
                    check_instance(p, want_p, "float32", POSITION_TOLERANCE)
                    check_instance(n, want_n, "float32", NORMAL_TOLERANCE, normals=True)
                    # Several tasks on one connection: the lock keeps each answer its own.
                    palettes = [random_palette(rng, JOINTS) for _ in range(6)]
                    answers = await asyncio.gather(*(
                        frames.skin(mesh_ids[1], q, frame=i) for i, q in enumerate(palettes)))
                    for got, q in zip(answers, palettes):
                        check_instance(got, skin(*meshes[1], q)[0], "float32",
                                       POSITION_TOLERANCE)
                    characters = make_tick(rng, mesh_ids, meshes)
                    results = await frames.tick(characters, frame=3)
                    for result, character, mesh in zip(results, characters, meshes):
                        check_result(result, character, mesh)
                    with pytest.raises(skinserve.SkinserveError) as e:
                        await frames.skin(mesh_ids[0], palette, backend="no-such", frame=9)
                    assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT and e.value.frame == 9
                    # Quiet for --stream-idle-seconds (2 s): the server's reason comes back.
                    await asyncio.sleep(3)
                    with pytest.raises(skinserve.SkinserveError) as e:
                        await frames.skin(mesh_ids[0], palette, frame=10)
                    assert e.value.code == grpc.StatusCode.UNAVAILABLE
                    assert "--stream-idle-seconds" in e.value.message, e.value.message
                await client.unregister_region(region)

    run(main())


def test_asyncio_socket_that_is_not_there_is_unavailable(socket_server, tmp_path):
    async def main():
        async with skinserve.AsyncClient(socket_server.unix_target) as client:
            with pytest.raises(skinserve.SkinserveError) as e:
                async with skinserve.AsyncFrameSocket(str(tmp_path / "none.sock"), client):
                    pass
            assert e.value.code == grpc.StatusCode.UNAVAILABLE
            assert "none.sock" in e.value.message

    run(main())
