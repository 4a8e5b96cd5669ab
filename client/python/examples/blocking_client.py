"""skinserve's blocking client: a mesh uploaded, one palette, a crowd and a stream skinned.

    python3 examples/blocking_client.py 127.0.0.1:50051
"""
import sys
from typing import Any, Dict

import numpy as np

import skinserve


def mesh() -> Dict[str, Any]:
    """A strip of 8 vertices along x, bound to 2 joints with weights blending across it."""
    x = np.linspace(0.0, 1.0, 8)
    positions = np.stack([x, np.zeros(8), np.zeros(8)], axis=1).astype(np.float32)
    joints = np.tile(np.array([0, 1], dtype=np.uint16), (8, 1))
    weights = np.stack([1 - x, x], axis=1).astype(np.float32)
    return {"positions": positions, "joints": joints, "weights": weights}


def palette(angle: float, lift: float) -> Any:
    """Joint 0 stays; joint 1 turns by `angle` about z and rises by `lift`: (2, 3, 4)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]],
                     [[c, -s, 0, 0], [s, c, 0, lift], [0, 0, 1, 0]]], dtype=np.float32)


def main(target: str) -> Dict[str, Any]:
    m = mesh()
    with skinserve.Client(target) as client:
        mesh_id = client.upload(m["positions"], m["joints"], m["weights"])
        single_palette = palette(0.5, 0.1)
        single = client.skin(mesh_id, single_palette)                     # (8, 3) float32
        crowd_palettes = np.stack([palette(a, 0.0) for a in (0.1, 0.2, 0.3)])
        crowd = client.skin(mesh_id, crowd_palettes, encoding="float16")  # (3, 8, 3)
        stream_palettes = [palette(0.1 * f, 0.05 * f) for f in range(5)]
        frames = list(client.stream(mesh_id, stream_palettes, encoding="snorm16"))
    print(f"mesh {mesh_id[:12]}: vertex 7 at {single[7]}, crowd {crowd.shape}, "
          f"{len(frames)} frames streamed")
    return {**m, "single_palette": single_palette, "single": single,
            "crowd_palettes": crowd_palettes, "crowd": crowd,
            "stream_palettes": stream_palettes, "frames": frames}


if __name__ == "__main__":
    main(sys.argv[1])
