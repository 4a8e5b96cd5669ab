"""skinserve.AsyncClient against a real server: every encoding, single palettes and crowds,
unary and streamed, into shared memory too, each answer against the float64 reference
within float32's rounding plus the encoding's bound (test_crowds_and_encodings.py)."""
import asyncio
import contextlib
import shutil
import tempfile

import grpc
import numpy as np
import pytest

import skinserve
from conftest import Server
from reference import random_mesh, random_palette, skin
from test_crowds_and_encodings import (ENCODINGS, POSITION_TOLERANCE, check_crowd,
                                       check_instance)

JOINTS = 30


def run(coroutine):
    return asyncio.run(asyncio.wait_for(coroutine, timeout=120))


def crowd_of(rng, k):
    return np.stack([random_palette(rng, JOINTS) for _ in range(k)])


@pytest.mark.parametrize("encoding", ENCODINGS)
def test_skin_single_and_crowds_in_every_encoding(server, rng, encoding):
    mesh = random_mesh(rng, 1500, 3, JOINTS)

    async def main():
        async with skinserve.AsyncClient(server.target) as client:
            mesh_id = await client.upload(*mesh)
            single = random_palette(rng, JOINTS)
            p, n = await client.skin(mesh_id, single, backend="sse", want_normals=True,
                                     encoding=encoding)
            assert p.shape == (1500, 3)  # a single palette answers one vertex set
            check_crowd(p[None], n[None], mesh, [single], encoding)
            for k in (1, 4):
                crowd = crowd_of(rng, k)
                p, n = await client.skin(mesh_id, crowd, backend="sse", want_normals=True,
                                         encoding=encoding)
                assert p.shape == (k, 1500, 3)
                check_crowd(p, n, mesh, crowd, encoding)
            # Positions alone: one array, not a tuple.
            p = await client.skin(mesh_id, single, backend="serial", encoding=encoding)
            assert isinstance(p, np.ndarray)
            check_instance(p, skin(*mesh, single)[0], encoding, POSITION_TOLERANCE)
    run(main())


@pytest.mark.parametrize("encoding", ENCODINGS)
def test_stream_mixes_crowds_and_single_palettes(server, rng, encoding):
    # 30k vertices with normals: a crowd of 3 in float32 spans several 1 MiB parts.
    mesh = random_mesh(rng, 30_000, 2, JOINTS)
    sizes = [None, 3, None, 1, 2, None, 5]
    palettes = [random_palette(rng, JOINTS) if k is None else crowd_of(rng, k) for k in sizes]

    async def main():
        async with skinserve.AsyncClient(server.target) as client:
            mesh_id = await client.upload(*mesh)
            return [frame async for frame in client.stream(
                mesh_id, palettes, backend="sse", want_normals=True, encoding=encoding,
                window=3)]
    frames = run(main())
    assert len(frames) == len(sizes)
    for k, palette, (p, n) in zip(sizes, palettes, frames):
        if k is None:
            check_crowd(p[None], n[None], mesh, [palette], encoding)
        else:
            check_crowd(p, n, mesh, palette, encoding)


def test_concurrent_calls_on_one_client(server, rng):
    # The point of asyncio: several frames in flight from one task's client at once.
    mesh = random_mesh(rng, 2000, 2, JOINTS)
    crowds = [crowd_of(rng, k) for k in (1, 2, 3, 4, 5, 6)]

    async def main():
        async with skinserve.AsyncClient(server.target) as client:
            mesh_id = await client.upload(*mesh)
            return await asyncio.gather(*(
                client.skin(mesh_id, c, backend="sse", want_normals=True, encoding=e)
                for c, e in zip(crowds, ENCODINGS * 2)))
    for crowd, encoding, (p, n) in zip(crowds, ENCODINGS * 2, run(main())):
        check_crowd(p, n, mesh, crowd, encoding)


def test_a_stream_closed_early_ends_its_call(server, rng):
    mesh = random_mesh(rng, 1000, 2, JOINTS)
    palettes = [random_palette(rng, JOINTS) for _ in range(200)]

    async def main():
        async with skinserve.AsyncClient(server.target) as client:
            mesh_id = await client.upload(*mesh)
            async with contextlib.aclosing(client.stream(mesh_id, palettes, backend="serial",
                                                         window=2)) as frames:
                got = [await frames.__anext__() for _ in range(3)]
            for _ in range(100):  # the server sees the cancellation a moment later
                if (await client.stats())["open_streams"] == 0:
                    return got
                await asyncio.sleep(0.05)
            raise AssertionError("the stream stayed open after aclose()")
    for got, palette in zip(run(main()), palettes):
        check_instance(got, skin(*mesh, palette)[0], "float32", POSITION_TOLERANCE)


def test_a_bad_instance_is_named_and_the_stream_stops_there(server, rng):
    mesh = random_mesh(rng, 800, 2, JOINTS)
    good = crowd_of(rng, 4)
    bad = good.copy()
    bad[2, 5, 0, 3] = np.nan  # instance 2 of 4

    async def main():
        async with skinserve.AsyncClient(server.target) as client:
            mesh_id = await client.upload(*mesh)
            answers = client.stream(mesh_id, [good, bad, good], backend="serial",
                                    want_normals=True)
            p, n = await answers.__anext__()  # the frame before the bad one, in full
            check_crowd(p, n, mesh, good, "float32")
            with pytest.raises(skinserve.SkinserveError) as e:
                await answers.__anext__()
            assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT and e.value.frame == 1
            assert "instance 2" in e.value.message
            p, n = await client.skin(mesh_id, good, backend="serial", want_normals=True)
            check_crowd(p, n, mesh, good, "float32")  # the client carries on
    run(main())


def test_reupload_after_the_server_lost_the_mesh(server, rng):
    mesh = random_mesh(rng, 500, 2, JOINTS)
    palette = random_palette(rng, JOINTS)

    async def main():
        async with skinserve.AsyncClient(server.target) as client:
            mesh_id = await client.upload(*mesh)
            with skinserve.Client(server.target) as other:  # loses it, as a replica would
                delete = skinserve._client.pb.DeleteMeshRequest(mesh_id=mesh_id)
                other._stub.DeleteMesh(delete)
                single = await client.skin(mesh_id, palette, backend="serial")
                other._stub.DeleteMesh(delete)
                streamed = [f async for f in client.stream(mesh_id, [palette] * 4,
                                                           backend="serial")]
            return single, streamed
    single, streamed = run(main())
    assert len(streamed) == 4
    want, _ = skin(*mesh, palette)
    for got in [single, *streamed]:
        check_instance(got, want, "float32", POSITION_TOLERANCE)


def test_errors_and_bad_input(server, rng):
    async def main():
        async with skinserve.AsyncClient(server.target) as client:
            with pytest.raises(skinserve.SkinserveError) as e:
                await client.skin("0" * 64, random_palette(rng, JOINTS))
            assert e.value.code == grpc.StatusCode.NOT_FOUND and "0" * 64 in e.value.message
            mesh_id = await client.upload(*random_mesh(rng, 100, 1, JOINTS))
            with pytest.raises(ValueError, match="encoding: 'int8'"):
                await client.skin(mesh_id, random_palette(rng, JOINTS), encoding="int8")
            with pytest.raises(ValueError, match="palette: dtype float64"):
                await client.skin(mesh_id, random_palette(rng, JOINTS).astype(np.float64))
            with pytest.raises(skinserve.SkinserveError) as e:
                await client.skin(mesh_id, np.stack([random_palette(rng, JOINTS)] * 65),
                                  backend="serial")
            assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT
            backends = await client.backends()
            assert sum(b["default"] for b in backends) == 1
            stats = await client.stats()
            assert set(stats["backends"]) == {b["id"] for b in backends}
    run(main())


def test_shared_memory_region_every_encoding(binary, rng):
    shm_dir = tempfile.mkdtemp(prefix="skinserve-py-aio-", dir="/dev/shm")
    server = Server(binary, "--shm-dir", shm_dir, unix_socket=True)
    mesh = random_mesh(rng, 1200, 3, JOINTS)
    crowd = crowd_of(rng, 3)

    async def main():
        async with skinserve.AsyncClient(server.unix_target) as client:
            mesh_id = await client.upload(*mesh)
            with skinserve.SharedMemoryRegion(4 << 20, directory=shm_dir) as region:
                await client.register_region(region)
                assert [r["name"] for r in await client.regions()] == [region.name]
                for encoding in ENCODINGS:
                    p, n = await client.skin(mesh_id, crowd, backend="sse", want_normals=True,
                                             encoding=encoding, region=region)
                    check_crowd(p.astype(np.float32), n.astype(np.float32), mesh, crowd,
                                encoding)
                    frames = [(p.astype(np.float32), n.astype(np.float32)) async for p, n in
                              client.stream(mesh_id, [crowd, crowd[0], crowd], backend="sse",
                                            want_normals=True, encoding=encoding, window=2,
                                            region=region)]
                    check_crowd(*frames[0], mesh, crowd, encoding)
                    check_crowd(frames[1][0][None], frames[1][1][None], mesh, [crowd[0]],
                                encoding)
                    check_crowd(*frames[2], mesh, crowd, encoding)
                await client.unregister_region(region)
                assert region.name is None and await client.regions() == []
    try:
        run(main())
    finally:
        server.stop()
        shutil.rmtree(shm_dir, ignore_errors=True)
