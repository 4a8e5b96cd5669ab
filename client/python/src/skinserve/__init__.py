"""skinserve: a Python client for the gRPC skinning service, blocking (Client) and
asyncio (AsyncClient), with the same methods.

    import numpy as np, skinserve
    client = skinserve.Client("127.0.0.1:50051")
    mesh_id = client.upload(positions, joints, weights)   # float32 (V,3), uint16 (V,B), float32 (V,B)
    vertices = client.skin(mesh_id, palette)              # palette float32 (J,3,4) -> (V,3) float32
    crowd = client.skin(mesh_id, palettes, encoding="snorm16")  # (K,J,3,4) -> (K,V,3)
    for vertices in client.stream(mesh_id, palettes, backend="sse"):
        ...
    # Morph targets: sparse deltas on upload, sparse weights {target: weight} per frame.
    mesh_id = client.upload(positions, joints, weights,
                            morph_targets=[skinserve.MorphTarget(indices, deltas)])
    vertices = client.skin(mesh_id, palette, morph_weights={0: 0.5})
    crowd = client.skin(mesh_id, palettes, morph_weights=[{0: 1.0}, {}])  # one per instance
    # On the server's host: the server skins into shared memory, the answer views it.
    with skinserve.SharedMemoryRegion(64 << 20) as region:
        client.register_region(region)
        vertices = client.skin(mesh_id, palette, region=region)

    # Frames and ticks on the server's frame socket (skinserve --frame-socket PATH), same host:
    with skinserve.FrameSocket("/run/skinserve/frames.sock", client) as frames:
        vertices = frames.skin(mesh_id, palette, region=region)   # AsyncFrameSocket: asyncio

    # A tick: many characters (each its mesh, palette and options) in one request.
    results = client.tick([skinserve.Character(mesh_a, palette_a),
                           skinserve.Character(mesh_b, crowd_b, want_normals=True)])
    for r in results:
        print(r.index, r.error or r.positions.shape)

    # Animation on the server: a skeleton and clips once, then poses instead of palettes.
    skeleton_id = client.upload_skeleton(parents, rest, palette_joints, inverse_bind)
    track = skinserve.ClipTrack("rotation", 1, times, quats)   # joint 1's keys, x y z w
    clip_id = client.upload_clip(skeleton_id, [track]).clip_id
    pose = skinserve.Pose(skeleton_id, [skinserve.PoseLayer(clip_id, 0.5)])
    vertices = client.skin_pose(mesh_id, pose)                 # the server's palette

    async with skinserve.AsyncClient("127.0.0.1:50051") as client:
        vertices = await client.skin(mesh_id, palette)
        async for vertices in client.stream(mesh_id, palettes):
            ...
"""
from ._aio_client import AsyncClient
from ._client import Client
from ._encoding import decode_values
from ._errors import SkinserveError
from ._frame_socket import AsyncFrameSocket, FrameSocket
from ._morph import FrameWeights, MorphTarget, Weights
from ._pose import ClipTrack, Pose, PoseLayer
from ._shared_memory import SharedMemoryRegion
from ._tick import Character, CharacterResult

__all__ = ["AsyncClient", "AsyncFrameSocket", "Character", "CharacterResult", "ClipTrack",
           "Client", "FrameSocket", "FrameWeights", "MorphTarget", "Pose", "PoseLayer",
           "SkinserveError", "SharedMemoryRegion", "Weights", "decode_values"]
