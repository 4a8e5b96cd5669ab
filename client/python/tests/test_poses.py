"""Poses on the server through the Python clients, blocking and asyncio: a two-joint
skeleton and a clip uploaded (the root walks 1 m along x in 1 s, the child turns 90 degrees
about z), frames that name clip layers instead of a palette, every answer against a
float64 evaluation written here from the clip's definition (the root at (t, 0, 0), the
child's angle 90 t degrees: LINEAR rotation keys are slerped, at a constant rate), the
layers blended as docs/serving/animation.md states, then linear blend skinning in float64
(reference.skin). Tolerance: the compact store's key error (<= 7.5e-5 rad, 1.5e-5 m over
this 1 m range) moving points up to ~3 m from the joints, plus float32 rounding."""
import asyncio
import math

import grpc
import numpy as np
import pytest

import skinserve
from reference import max_error, random_mesh, skin

TOLERANCE = 5e-4
IDENTITY = (0.0, 0.0, 0.0, 1.0)


def turn(degrees):
    half = math.radians(degrees) / 2
    return (0.0, 0.0, math.sin(half), math.cos(half))


def rig():
    """upload_skeleton's arguments and the clip's tracks."""
    rest = np.array([[0, 0, 0, *IDENTITY, 1, 1, 1], [0, 1, 0, *IDENTITY, 1, 1, 1]], np.float32)
    inverse_bind = np.zeros((2, 3, 4), np.float32)
    inverse_bind[:, :, :3] = np.eye(3)
    inverse_bind[1, 1, 3] = -1  # the child's rest model is a translation by (0, 1, 0)
    skeleton = (np.array([-1, 0], np.int16), rest, np.array([0, 1], np.uint16), inverse_bind)
    times = np.array([0, 1], np.float32)
    tracks = [skinserve.ClipTrack("translation", 0, times, np.array([[0, 0, 0], [1, 0, 0]])),
              skinserve.ClipTrack("rotation", 1, times, np.array([IDENTITY, turn(90)]))]
    return skeleton, tracks


def upload_rig(client):
    skeleton, tracks = rig()
    skeleton_id = client.upload_skeleton(*skeleton)
    info = client.upload_clip(skeleton_id, tracks, name="walk-turn")
    return skeleton_id, info


def quat_matrix(q):
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def reference_palette(layers):
    """layers: (time in [0, 1], weight); normalised weights, rotations summed and
    normalised (all on one hemisphere here), model matrices, times the inverse binds."""
    total = sum(w for _, w in layers)
    root = sum(w / total * t for t, w in layers)
    q = np.sum([w / total * np.array(turn(90 * t)) for t, w in layers], axis=0)
    q /= np.linalg.norm(q)
    def affine(rotation, translation):
        m = np.eye(4)
        m[:3, :3], m[:3, 3] = rotation, translation
        return m
    model0 = affine(np.eye(3), (root, 0, 0))
    model1 = model0 @ affine(np.eye(3), (0, 1, 0)) @ affine(quat_matrix(q), (0, 0, 0))
    palette1 = model1 @ affine(np.eye(3), (0, -1, 0))
    return np.stack([model0[:3], palette1[:3]])


def check(answer, mesh, layers):
    positions, joint_ids, weights, _ = mesh
    want, _ = skin(positions, joint_ids, weights, None, reference_palette(layers))
    assert max_error(answer, want) <= TOLERANCE


def test_poses_match_the_float64_evaluation_of_the_clip(client, rng):
    skeleton_id, info = upload_rig(client)
    assert info.joint_count == 2 and info.tracks == 2 and not info.already_stored
    mesh = random_mesh(rng, 500, 2, 2)
    mesh_id = client.upload(*mesh[:3])
    clip = info.clip_id
    for layers, want in [
            ([skinserve.PoseLayer(clip, 0.3)], [(0.3, 1)]),
            ([skinserve.PoseLayer(clip, 1.7)], [(1.0, 1)]),                # clamped
            ([skinserve.PoseLayer(clip, 1.25, loop=True)], [(0.25, 1)]),   # looped
            ([skinserve.PoseLayer(clip, 0.2, 1), skinserve.PoseLayer(clip, 0.6, 3)],
             [(0.2, 1), (0.6, 3)])]:
        check(client.skin_pose(mesh_id, skinserve.Pose(skeleton_id, layers), backend="serial"),
              mesh, want)
    # The same skeleton and clip again: stored once.
    assert upload_rig(client)[1].already_stored


def test_clips_stored_to_a_chosen_error(client, rng):
    """upload_clip(max_error_mm=...): the server stores the clip to that bound (ClipInfo says
    it; another bound is another clip), poses from it still match the float64 evaluation
    within this file's tolerance (1 mm moves these points < 5e-4 m: 2 keys are stored at
    the ends of their ranges, exactly), and a bound outside 0.01..10 mm is refused naming
    the field and its limits."""
    skeleton, tracks = rig()
    skeleton_id = client.upload_skeleton(*skeleton)
    default = client.upload_clip(skeleton_id, tracks, name="walk-turn")
    loose = client.upload_clip(skeleton_id, tracks, name="walk-turn", max_error_mm=1.0)
    assert default.max_error_mm == pytest.approx(0.01)
    assert loose.max_error_mm == pytest.approx(1.0)
    assert loose.clip_id != default.clip_id and not loose.already_stored
    assert loose.bytes < default.bytes and loose.raw_bytes == default.raw_bytes
    mesh = random_mesh(rng, 500, 2, 2)
    mesh_id = client.upload(*mesh[:3])
    for t in (0.3, 0.77):
        layers = [skinserve.PoseLayer(loose.clip_id, t)]
        check(client.skin_pose(mesh_id, skinserve.Pose(skeleton_id, layers), backend="serial"),
              mesh, [(t, 1)])
    for bad in (-1.0, 0.001, 25.0):
        with pytest.raises(skinserve.SkinserveError) as e:
            client.upload_clip(skeleton_id, tracks, max_error_mm=bad)
        assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT
        assert "max_error_mm" in e.value.message and "[0.01, 10] mm" in e.value.message


def test_bad_poses_are_named(client, rng):
    skeleton_id, info = upload_rig(client)
    mesh_id = client.upload(*random_mesh(rng, 50, 2, 2)[:3])
    with pytest.raises(skinserve.SkinserveError) as e:
        client.skin_pose(mesh_id, skinserve.Pose(skeleton_id, [skinserve.PoseLayer("nope", 0)]))
    assert e.value.code == grpc.StatusCode.NOT_FOUND
    assert "pose.layers[0].clip_id 'nope'" in e.value.message
    with pytest.raises(skinserve.SkinserveError) as e:
        client.skin_pose(mesh_id, skinserve.Pose(
            skeleton_id, [skinserve.PoseLayer(info.clip_id, 0.1, weight=-1)]))
    assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT
    assert "pose.layers[0].weight = -1" in e.value.message
    # stats() reports the animation store: deleting the clip gives its bytes back.
    before = client.stats()
    assert before["skeletons"] >= 1 and before["clips"] >= 1
    assert client.delete_clip(info.clip_id)
    after = client.stats()
    assert after["clips"] == before["clips"] - 1
    assert after["clip_bytes"] == before["clip_bytes"] - info.bytes
    assert after["clip_budget_bytes"] == before["clip_budget_bytes"] > 0
    assert not client.delete_clip(info.clip_id)


def test_asyncio_poses(server, rng):
    async def main():
        async with skinserve.AsyncClient(server.target) as client:
            # The rig through the blocking client's request builders (both share them).
            with skinserve.Client(server.target) as blocking:
                skeleton_id, info = upload_rig(blocking)
            mesh = random_mesh(rng, 300, 2, 2)
            mesh_id = await client.upload(*mesh[:3])
            layers = [skinserve.PoseLayer(info.clip_id, 0.4, 2),
                      skinserve.PoseLayer(info.clip_id, 0.9, 1)]
            check(await client.skin_pose(mesh_id, skinserve.Pose(skeleton_id, layers)), mesh,
                  [(0.4, 2), (0.9, 1)])
            assert await client.delete_clip(info.clip_id)
    asyncio.run(asyncio.wait_for(main(), timeout=120))


def pose(skeleton_id, clip, layers):
    """A skinserve.Pose of `layers` ((time, weight) each) of one clip."""
    return skinserve.Pose(skeleton_id, [skinserve.PoseLayer(clip, t, w) for t, w in layers])


# A stream's frames: a pose, a palette, a blend of two layers, a palette, a pose; each
# (what is sent, the layers its answer is checked against).
STREAM_FRAMES = [[(0.1, 1)], [(0.5, 1)], [(0.2, 1), (0.7, 3)], [(0.35, 2)], [(0.9, 1)]]


def stream_inputs(skeleton_id, clip):
    """STREAM_FRAMES as the stream's entries: odd ones as the palette the client computed
    (float32, from the float64 reference), the others as poses for the server."""
    return [reference_palette(layers).astype(np.float32) if i % 2 == 1
            else pose(skeleton_id, clip, layers) for i, layers in enumerate(STREAM_FRAMES)]


# A tick's characters: pose, palette, blend, and a bad pose (negative weight) that fails
# alone, named; each tick moves the good ones on by `shift` seconds.
def tick_characters(mesh_id, skeleton_id, clip, shift):
    wants = [[(0.2 + shift, 1)], [(0.6 + shift, 1)], [(0.1 + shift, 1), (0.8 - shift, 2)]]
    characters = [skinserve.Character(mesh_id, pose=pose(skeleton_id, clip, wants[0])),
                  skinserve.Character(mesh_id, reference_palette(wants[1]).astype(np.float32)),
                  skinserve.Character(mesh_id, pose=pose(skeleton_id, clip, wants[2]),
                                      backend="serial"),
                  skinserve.Character(mesh_id, pose=pose(skeleton_id, clip, [(0.3, -1)]))]
    return characters, wants


def check_tick(results, mesh, wants):
    assert len(results) == 4
    for i, want in enumerate(wants):
        assert results[i].ok, results[i].error
        check(results[i].positions, mesh, want)
    assert results[3].error.code == grpc.StatusCode.INVALID_ARGUMENT
    assert "character 3: pose.layers[0].weight = -1" in results[3].error.message


def test_streams_send_each_frames_pose_or_palette(client, rng):
    skeleton_id, info = upload_rig(client)
    mesh = random_mesh(rng, 400, 2, 2)
    mesh_id = client.upload(*mesh[:3])
    answers = list(client.stream(mesh_id, stream_inputs(skeleton_id, info.clip_id), window=2))
    assert len(answers) == len(STREAM_FRAMES)
    for answer, layers in zip(answers, STREAM_FRAMES):
        check(answer, mesh, layers)


def test_ticks_carry_poses_beside_palettes(client, rng):
    skeleton_id, info = upload_rig(client)
    mesh = random_mesh(rng, 400, 2, 2)
    mesh_id = client.upload(*mesh[:3])
    characters, wants = tick_characters(mesh_id, skeleton_id, info.clip_id, 0.0)
    check_tick(client.tick(characters, frame=4), mesh, wants)
    ticks = [tick_characters(mesh_id, skeleton_id, info.clip_id, 0.05 * i) for i in range(3)]
    answered = list(client.stream_ticks([characters for characters, _ in ticks], window=2))
    assert len(answered) == 3
    for results, (_, wants) in zip(answered, ticks):
        check_tick(results, mesh, wants)


def test_poses_are_checked_before_sending(client, rng):
    skeleton_id, info = upload_rig(client)
    mesh_id = client.upload(*random_mesh(rng, 50, 2, 2)[:3])
    palette = reference_palette([(0.5, 1)]).astype(np.float32)
    good = pose(skeleton_id, info.clip_id, [(0.5, 1)])
    with pytest.raises(ValueError, match=r"characters\[0\]: give a palette or a pose .*both"):
        client.tick([skinserve.Character(mesh_id, palette, pose=good)])
    with pytest.raises(ValueError, match=r"characters\[1\]: give a palette or a pose .*neither"):
        client.tick([skinserve.Character(mesh_id, palette), skinserve.Character(mesh_id)])
    with pytest.raises(ValueError, match=r"palettes\[1\].layers: 0 layers, expected 1..8"):
        list(client.stream(mesh_id, [good, skinserve.Pose(skeleton_id, [])]))
    with pytest.raises(ValueError, match=r"characters\[0\].pose.layers\[0\]: tuple"):
        client.tick([skinserve.Character(mesh_id, pose=skinserve.Pose(skeleton_id,
                                                                      [(info.clip_id, 0.5)]))])


def test_asyncio_streams_and_ticks_with_poses(server, rng):
    async def main():
        async with skinserve.AsyncClient(server.target) as client:
            with skinserve.Client(server.target) as blocking:
                skeleton_id, info = upload_rig(blocking)
            mesh = random_mesh(rng, 300, 2, 2)
            mesh_id = await client.upload(*mesh[:3])
            answers = [a async for a in client.stream(
                mesh_id, stream_inputs(skeleton_id, info.clip_id), window=2)]
            assert len(answers) == len(STREAM_FRAMES)
            for answer, layers in zip(answers, STREAM_FRAMES):
                check(answer, mesh, layers)
            characters, wants = tick_characters(mesh_id, skeleton_id, info.clip_id, 0.1)
            check_tick(await client.tick(characters, frame=2), mesh, wants)
            ticks = [tick_characters(mesh_id, skeleton_id, info.clip_id, 0.03 * i)
                     for i in range(2)]
            answered = [r async for r in client.stream_ticks([c for c, _ in ticks])]
            assert len(answered) == 2
            for results, (_, wants) in zip(answered, ticks):
                check_tick(results, mesh, wants)
    asyncio.run(asyncio.wait_for(main(), timeout=120))
