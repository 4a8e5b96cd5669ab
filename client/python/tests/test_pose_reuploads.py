"""A skeleton or clip the server lost is uploaded again by the client that uploaded it, and
the pose frame sent again, as the C++ client library does (SkinClient::Reupload): the clip
deleted by another client between calls and in the middle of a stream, the whole store lost
to a server restart (mesh, skeleton and clip) before a frame and a tick, blocking and
asyncio. Every answer is checked against the float64 evaluation of test_poses (the clip
written out by hand, skinned in double)."""
import asyncio

import grpc
import pytest

import skinserve
from conftest import Server
from reference import random_mesh
from test_poses import check, pose, rig, upload_rig


@pytest.fixture
def own_server(binary):
    """A server of this test's own: restarting it loses everything uploaded."""
    s = Server(binary)
    yield s
    s.stop()


def test_a_deleted_clip_is_uploaded_again(server, rng):
    with skinserve.Client(server.target) as client, skinserve.Client(server.target) as other:
        skeleton_id, info = upload_rig(client)
        mesh = random_mesh(rng, 300, 2, 2)
        mesh_id = client.upload(*mesh[:3])
        assert other.delete_clip(info.clip_id)
        check(client.skin_pose(mesh_id, pose(skeleton_id, info.clip_id, [(0.3, 1)])), mesh,
              [(0.3, 1)])
        assert other.delete_clip(info.clip_id), "the clip was back on the server"


def test_a_clip_deleted_mid_stream_is_uploaded_again_and_the_stream_resumes(server, rng):
    with skinserve.Client(server.target) as client, skinserve.Client(server.target) as other:
        skeleton_id, info = upload_rig(client)
        mesh = random_mesh(rng, 300, 2, 2)
        mesh_id = client.upload(*mesh[:3])
        times = [0.1 * i for i in range(8)]
        frames = client.stream(mesh_id, [pose(skeleton_id, info.clip_id, [(t, 1)])
                                         for t in times], window=1)
        answers = [next(frames)]
        assert other.delete_clip(info.clip_id)  # frame 1 may be answered; 2.. are not
        answers.extend(frames)
        assert len(answers) == len(times)
        for answer, t in zip(answers, times):
            check(answer, mesh, [(t, 1)])
        assert other.delete_clip(info.clip_id), "the clip was back on the server"


def test_a_restarted_server_gets_the_mesh_skeleton_and_clip_again(own_server, rng):
    with skinserve.Client(own_server.target) as client:
        skeleton_id, info = upload_rig(client)
        mesh = random_mesh(rng, 300, 2, 2)
        mesh_id = client.upload(*mesh[:3])
        own_server.restart()
        check(client.skin_pose(mesh_id, pose(skeleton_id, info.clip_id, [(0.6, 1)])), mesh,
              [(0.6, 1)])
        stats = client.stats()
        assert stats["skeletons"] == 1 and stats["clips"] == 1
        own_server.restart()
        results = client.tick([skinserve.Character(mesh_id, pose=pose(skeleton_id, info.clip_id,
                                                                      [(0.2 + 0.3 * i, 1)]))
                               for i in range(3)])
        for i, r in enumerate(results):
            assert r.ok, r.error
            check(r.positions, mesh, [(0.2 + 0.3 * i, 1)])


def test_a_skeleton_this_client_never_uploaded_is_not_sent(own_server, rng):
    """Another client's skeleton lost: the NOT_FOUND naming it is raised, nothing sent."""
    with skinserve.Client(own_server.target) as client, \
            skinserve.Client(own_server.target) as other:
        skeleton_id, info = upload_rig(other)
        mesh = random_mesh(rng, 100, 2, 2)
        mesh_id = client.upload(*mesh[:3])
        own_server.restart()
        with pytest.raises(skinserve.SkinserveError) as e:
            client.skin_pose(mesh_id, pose(skeleton_id, info.clip_id, [(0.5, 1)]))
        assert e.value.code == grpc.StatusCode.NOT_FOUND
        assert f"pose.skeleton_id '{skeleton_id}'" in e.value.message


def test_asyncio_reuploads_a_lost_clip_and_skeleton(own_server, rng):
    async def main():
        async with skinserve.AsyncClient(own_server.target) as client:
            skeleton, tracks = rig()
            skeleton_id = await client.upload_skeleton(*skeleton)
            info = await client.upload_clip(skeleton_id, tracks, name="walk-turn")
            mesh = random_mesh(rng, 200, 2, 2)
            mesh_id = await client.upload(*mesh[:3])
            with skinserve.Client(own_server.target) as other:
                assert other.delete_clip(info.clip_id)
            check(await client.skin_pose(mesh_id, pose(skeleton_id, info.clip_id, [(0.4, 1)])),
                  mesh, [(0.4, 1)])
            own_server.restart()
            answers = [a async for a in client.stream(
                mesh_id, [pose(skeleton_id, info.clip_id, [(t, 1)]) for t in (0.1, 0.8)])]
            for answer, t in zip(answers, (0.1, 0.8)):
                check(answer, mesh, [(t, 1)])
            assert len(answers) == 2
    asyncio.run(asyncio.wait_for(main(), timeout=120))
