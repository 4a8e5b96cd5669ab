"""skinserve's blocking client with morph targets: a mesh uploaded with two sparse targets,
then frames that name their active targets' weights (for the whole frame, or one set per
instance of a crowd), unary and streamed.

    python3 examples/morph_client.py 127.0.0.1:50051
"""
import sys
from typing import Any, Dict, List

import numpy as np

import skinserve
from blocking_client import mesh, palette


def targets() -> List[skinserve.MorphTarget]:
    """Target 0 raises the strip's middle vertices 2..5 ("smile"); target 1 pushes its last
    two along z. Sparse: each lists only the vertices it moves."""
    smile = skinserve.MorphTarget(np.array([2, 3, 4, 5], dtype=np.uint32),
                                  np.tile(np.array([0, 0.2, 0], dtype=np.float32), (4, 1)))
    push = skinserve.MorphTarget(np.array([6, 7], dtype=np.uint32),
                                 np.array([[0, 0, 0.1], [0, 0, 0.3]], dtype=np.float32))
    return [smile, push]


def main(target: str) -> Dict[str, Any]:
    m, t = mesh(), targets()
    with skinserve.Client(target) as client:
        mesh_id = client.upload(m["positions"], m["joints"], m["weights"], morph_targets=t)
        single_palette = palette(0.5, 0.1)
        single_weights = {0: 0.75}                    # {target: weight}; the others weigh 0
        single = client.skin(mesh_id, single_palette, morph_weights=single_weights)
        crowd_palettes = np.stack([palette(a, 0.0) for a in (0.1, 0.2, 0.3)])
        crowd_weights: List[skinserve.Weights] = [{0: 1.0}, {}, {0: -0.5, 1: 1.0}]  # per instance
        crowd = client.skin(mesh_id, crowd_palettes, morph_weights=crowd_weights)
        stream_palettes = [palette(0.1 * f, 0.0) for f in range(5)]
        stream_weights = [{0: f / 4} for f in range(5)]  # one per frame: the smile grows
        frames = list(client.stream(mesh_id, stream_palettes, morph_weights=stream_weights))
    print(f"mesh {mesh_id[:12]}: vertex 3 at {single[3]}, crowd {crowd.shape}, "
          f"{len(frames)} frames streamed")
    return {**m, "targets": t, "single_palette": single_palette,
            "single_weights": single_weights, "single": single,
            "crowd_palettes": crowd_palettes, "crowd_weights": crowd_weights, "crowd": crowd,
            "stream_palettes": stream_palettes, "stream_weights": stream_weights,
            "frames": frames}


if __name__ == "__main__":
    main(sys.argv[1])
