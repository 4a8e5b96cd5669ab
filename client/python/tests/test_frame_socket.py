"""The frame socket from Python (skinserve.FrameSocket): regions registered over gRPC on
the server's Unix socket, frames sent over its --frame-socket, every answer checked against
the float64 reference; a frame's error leaves the connection going; the server's reason
when it ends one."""
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
