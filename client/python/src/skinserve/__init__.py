"""skinserve: a Python client for the gRPC skinning service.

    import numpy as np, skinserve
    client = skinserve.Client("127.0.0.1:50051")
    mesh_id = client.upload(positions, joints, weights)   # float32 (V,3), uint16 (V,B), float32 (V,B)
    vertices = client.skin(mesh_id, palette)              # palette float32 (J,3,4) -> (V,3) float32
    crowd = client.skin(mesh_id, palettes, encoding="snorm16")  # (K,J,3,4) -> (K,V,3)
    for vertices in client.stream(mesh_id, palettes, backend="sse"):
        ...
"""
from ._client import Client, SkinserveError
from ._encoding import decode_values

__all__ = ["Client", "SkinserveError", "decode_values"]
