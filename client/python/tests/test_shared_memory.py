"""The same-host data plane from Python: regions made here, registered with a real server
on this host (its --shm-dir a fresh folder under /dev/shm), frames written into them and
answered as NumPy arrays that view the region, checked against the float64 reference."""
import os

import grpc
import numpy as np
import pytest

import skinserve
from conftest import Server
from reference import random_mesh, random_palette, skin
from test_crowds_and_encodings import NORMAL_TOLERANCE, POSITION_TOLERANCE, check_instance

JOINTS = 30


@pytest.fixture(scope="module")
def shm_server(binary, shm_dir):
    s = Server(binary, "--shm-dir", shm_dir, unix_socket=True)
    yield s
    s.stop()


@pytest.fixture
def shm_client(shm_server):
    with skinserve.Client(shm_server.unix_target) as c:
        yield c


def views(array, region):
    """Whether `array` reads the region's memory in place."""
    return np.shares_memory(array, np.frombuffer(region.buffer, dtype=np.uint8))


@pytest.mark.parametrize("encoding", ["float32", "float16", "snorm16"])
def test_frames_land_in_the_region_in_every_encoding_and_crowd_size(shm_client, shm_dir, rng,
                                                                     encoding):
    mesh = random_mesh(rng, 1200, 3, JOINTS)
    mesh_id = shm_client.upload(*mesh)
    with skinserve.SharedMemoryRegion(4 << 20, directory=shm_dir) as region:
        shm_client.register_region(region)
        for k in (None, 3):
            palettes = np.stack([random_palette(rng, JOINTS) for _ in range(k or 1)])
            p, n = shm_client.skin(mesh_id, palettes if k else palettes[0], want_normals=True,
                                   encoding=encoding, region=region, offset=128)
            if k is None:
                p, n = p[None], n[None]
            assert views(p, region) == (encoding != "snorm16")  # snorm16 is decoded
            for i, palette in enumerate(palettes):
                want_p, want_n = skin(*mesh, palette)
                check_instance(p[i].astype(np.float32), want_p, encoding, POSITION_TOLERANCE)
                check_instance(n[i].astype(np.float32), want_n, encoding, NORMAL_TOLERANCE,
                               normals=True)
        assert any(r["name"] == region.name for r in shm_client.regions())
        shm_client.unregister_region(region)
        assert not any(r["name"] == region.key for r in shm_client.regions())


def test_a_stream_writes_each_frame_into_its_own_slot(shm_client, shm_dir, rng):
    mesh = random_mesh(rng, 5000, 4, JOINTS)
    mesh_id = shm_client.upload(*mesh)
    palettes = [random_palette(rng, JOINTS) for _ in range(12)]
    with skinserve.SharedMemoryRegion(1 << 20, directory=shm_dir) as region:
        shm_client.register_region(region, name="py-stream")
        frames = 0
        for i, p in enumerate(shm_client.stream(mesh_id, palettes, window=4, region=region)):
            assert views(p, region)
            check_instance(p, skin(*mesh, palettes[i])[0], "float32", POSITION_TOLERANCE)
            frames += 1
        assert frames == len(palettes)
        shm_client.unregister_region(region)


def test_a_region_too_small_or_unknown_is_refused_naming_it(shm_client, shm_dir, rng):
    mesh = random_mesh(rng, 1000, 2, JOINTS)
    mesh_id = shm_client.upload(*mesh)
    palette = random_palette(rng, JOINTS)
    with skinserve.SharedMemoryRegion(4096, directory=shm_dir) as region:
        shm_client.register_region(region, name="tiny")
        with pytest.raises(skinserve.SkinserveError) as error:
            shm_client.skin(mesh_id, palette, region=region)
        assert error.value.code == grpc.StatusCode.INVALID_ARGUMENT
        assert "'tiny'" in error.value.message and "4096 bytes" in error.value.message
        shm_client.unregister_region(region)
        region.name = "tiny"  # unregistered: the server no longer knows it
        with pytest.raises(skinserve.SkinserveError) as error:
            shm_client.skin(mesh_id, palette, region=region)
        assert error.value.code == grpc.StatusCode.FAILED_PRECONDITION
        assert "'tiny'" in error.value.message
    stats = shm_client.stats()
    assert not any(r["name"] == "tiny" for r in shm_client.regions())
    assert stats["region_frames"] > 0


def test_regions_over_tcp_are_refused_saying_where_to_go(shm_server, shm_dir):
    with skinserve.Client(shm_server.target) as tcp, \
            skinserve.SharedMemoryRegion(4096, directory=shm_dir) as region:
        for call in (tcp.regions, lambda: tcp.register_region(region, name="tcp")):
            with pytest.raises(skinserve.SkinserveError) as error:
                call()
            assert error.value.code == grpc.StatusCode.PERMISSION_DENIED
            assert "Unix socket" in error.value.message and shm_dir not in error.value.message
