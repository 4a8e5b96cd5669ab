"""skinserve's asyncio client: the blocking example's calls as coroutines, several frames
in flight at once from one task.

    python3 examples/asyncio_client.py 127.0.0.1:50051
"""
import asyncio
import sys
from typing import Any, Dict

import numpy as np

import skinserve
from blocking_client import mesh, palette


async def main(target: str) -> Dict[str, Any]:
    m = mesh()
    async with skinserve.AsyncClient(target) as client:
        mesh_id = await client.upload(m["positions"], m["joints"], m["weights"])
        single_palette = palette(0.5, 0.1)
        single = await client.skin(mesh_id, single_palette)               # (8, 3) float32
        crowd_palettes = np.stack([palette(a, 0.0) for a in (0.1, 0.2, 0.3)])
        crowd = await client.skin(mesh_id, crowd_palettes, encoding="float16")
        stream_palettes = [palette(0.1 * f, 0.05 * f) for f in range(5)]
        frames = [f async for f in client.stream(mesh_id, stream_palettes, encoding="snorm16")]
        # Frames in flight together: one coroutine each, answers in the order asked.
        gathered = await asyncio.gather(*(client.skin(mesh_id, p) for p in stream_palettes))
    print(f"mesh {mesh_id[:12]}: vertex 7 at {single[7]}, crowd {crowd.shape}, "
          f"{len(frames)} frames streamed, {len(gathered)} gathered")
    return {**m, "single_palette": single_palette, "single": single,
            "crowd_palettes": crowd_palettes, "crowd": crowd,
            "stream_palettes": stream_palettes, "frames": frames, "gathered": gathered}


if __name__ == "__main__":
    asyncio.run(main(sys.argv[1]))
