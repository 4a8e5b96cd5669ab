"""Morph targets through a real server, blocking and asyncio: a mesh uploaded with sparse
targets, frames with sparse weights (one set for the frame, or one per crowd instance,
streamed frame by frame), every answer against a float64 reference written here: the
deltas summed in float64 target by target onto the rest arrays, then linear blend skinning
in float64 (reference.skin). Tolerances: float32's rounding of |M p| <= ~5 and of the ~10
terms summed per morphed value (a few ulp, ~2e-6); 2e-5 still fails on a lost or misplaced
target (deltas up to 0.1 times weights up to 1)."""
import asyncio

import numpy as np
import pytest

import skinserve
from reference import random_mesh, random_palette, skin

JOINTS = 20
VERTICES = 900
TARGETS = 10
POSITION_TOLERANCE = 2e-5
NORMAL_TOLERANCE = 2e-5


def random_targets(rng, vertices, count, normals=True):
    """Targets moving a random 15% of the vertices each (ascending indices)."""
    targets = []
    for _ in range(count):
        indices = np.sort(rng.choice(vertices, size=vertices * 15 // 100, replace=False))
        deltas = rng.uniform(-0.1, 0.1, size=(len(indices), 3)).astype(np.float32)
        normal_deltas = (rng.uniform(-0.1, 0.1, size=(len(indices), 3)).astype(np.float32)
                         if normals else None)
        targets.append(skinserve.MorphTarget(indices.astype(np.uint32), deltas, normal_deltas))
    return targets


def random_weights(rng, active):
    chosen = rng.choice(TARGETS, size=active, replace=False)
    return {int(t): float(rng.uniform(-1, 1)) for t in chosen}


def morph_and_skin(mesh, targets, weights, palette):
    """Float64: rest + sum_t w_t delta_t (positions and normals), then skinned."""
    positions, joint_ids, skin_weights, normals = mesh
    p = positions.astype(np.float64)
    n = normals.astype(np.float64)
    for t, w in (weights or {}).items():
        p[targets[t].indices] += w * targets[t].positions.astype(np.float64)
        if targets[t].normals is not None:
            n[targets[t].indices] += w * targets[t].normals.astype(np.float64)
    return skin(p, joint_ids, skin_weights, n, palette)


def check(got_p, got_n, mesh, targets, weights, palette, what):
    want_p, want_n = morph_and_skin(mesh, targets, weights, palette)
    assert got_p.dtype == np.float32 and got_p.shape == want_p.shape, what
    error_p = float(np.max(np.abs(got_p.astype(np.float64) - want_p)))
    error_n = float(np.max(np.abs(got_n.astype(np.float64) - want_n)))
    assert error_p <= POSITION_TOLERANCE, (what, error_p)  # NaN fails
    assert error_n <= NORMAL_TOLERANCE, (what, error_n)


def morph_backends(client):
    ids = [b["id"] for b in client.backends() if b["available"] and b["morph_targets"]]
    assert {"serial", "simd"} <= set(ids), ids
    return ids


@pytest.fixture
def morph_mesh(rng):
    return random_mesh(rng, VERTICES, 3, JOINTS), random_targets(rng, VERTICES, TARGETS)


def test_frames_single_and_crowds_match_on_every_morph_backend(client, rng, morph_mesh):
    mesh, targets = morph_mesh
    mesh_id = client.upload(*mesh[:3], normals=mesh[3], morph_targets=targets)
    # The reference does not move when no weight is given: the morph changes the answer.
    palette = random_palette(rng, JOINTS)
    weights = random_weights(rng, 4)
    plain = client.skin(mesh_id, palette, backend="serial")
    assert float(np.max(np.abs(plain - client.skin(mesh_id, palette, backend="serial",
                                                  morph_weights=weights)))) > 1e-3
    for backend in morph_backends(client):
        p, n = client.skin(mesh_id, palette, backend=backend, want_normals=True,
                           morph_weights=weights)
        check(p, n, mesh, targets, weights, palette, backend)
        crowd = np.stack([random_palette(rng, JOINTS) for _ in range(3)])
        # One set of weights for every instance of the crowd...
        p, n = client.skin(mesh_id, crowd, backend=backend, want_normals=True,
                           morph_weights=weights)
        for k in range(3):
            check(p[k], n[k], mesh, targets, weights, crowd[k], f"{backend} shared {k}")
        # ... or each instance its own (the second none at all).
        per_instance = [random_weights(rng, 3), {}, random_weights(rng, TARGETS)]
        p, n = client.skin(mesh_id, crowd, backend=backend, want_normals=True,
                           morph_weights=per_instance)
        for k in range(3):
            check(p[k], n[k], mesh, targets, per_instance[k], crowd[k], f"{backend} own {k}")


def test_stream_carries_each_frames_weights(client, rng, morph_mesh):
    mesh, targets = morph_mesh
    mesh_id = client.upload(*mesh[:3], normals=mesh[3], morph_targets=targets)
    palettes = [random_palette(rng, JOINTS) for _ in range(4)]
    palettes += [np.stack([random_palette(rng, JOINTS) for _ in range(2)]) for _ in range(2)]
    weights = [random_weights(rng, 4), None, {}, random_weights(rng, 2),
               random_weights(rng, 5), [random_weights(rng, 1), random_weights(rng, 6)]]
    answers = list(client.stream(mesh_id, palettes, backend="simd", want_normals=True,
                                 window=3, morph_weights=weights))
    assert len(answers) == len(palettes)
    for i, ((p, n), palette, w) in enumerate(zip(answers, palettes, weights)):
        if palette.ndim == 3:
            check(p, n, mesh, targets, w, palette, f"frame {i}")
            continue
        for k in range(palette.shape[0]):
            own = w[k] if isinstance(w, list) else w
            check(p[k], n[k], mesh, targets, own, palette[k], f"frame {i} instance {k}")


def test_asyncio_client_uploads_targets_and_sends_weights(server, rng, morph_mesh):
    mesh, targets = morph_mesh

    async def main():
        async with skinserve.AsyncClient(server.target) as client:
            mesh_id = await client.upload(*mesh[:3], normals=mesh[3], morph_targets=targets)
            palette = random_palette(rng, JOINTS)
            weights = random_weights(rng, 4)
            p, n = await client.skin(mesh_id, palette, backend="simd-openmp",
                                     want_normals=True, morph_weights=weights)
            check(p, n, mesh, targets, weights, palette, "asyncio skin")
            crowd = np.stack([random_palette(rng, JOINTS) for _ in range(2)])
            per_instance = [random_weights(rng, 2), random_weights(rng, 7)]
            p, n = await client.skin(mesh_id, crowd, want_normals=True,
                                     morph_weights=per_instance)
            for k in range(2):
                check(p[k], n[k], mesh, targets, per_instance[k], crowd[k], f"asyncio {k}")
            palettes = [random_palette(rng, JOINTS) for _ in range(3)]
            frames = [random_weights(rng, 3), None, random_weights(rng, 1)]
            i = 0
            async for p, n in client.stream(mesh_id, palettes, want_normals=True,
                                            morph_weights=frames):
                check(p, n, mesh, targets, frames[i], palettes[i], f"asyncio frame {i}")
                i += 1
            assert i == 3

    asyncio.run(asyncio.wait_for(main(), timeout=120))


def test_bad_targets_and_weights_are_refused_naming_them(client, rng, morph_mesh):
    mesh, targets = morph_mesh
    with pytest.raises(ValueError, match=r"morph_targets\[1\].positions: shape"):
        bad = [targets[0], skinserve.MorphTarget(targets[1].indices, targets[1].positions[1:],
                                                 targets[1].normals)]
        client.upload(*mesh[:3], normals=mesh[3], morph_targets=bad)
    with pytest.raises(ValueError, match="some targets have normal deltas and some not"):
        client.upload(*mesh[:3], normals=mesh[3],
                      morph_targets=[targets[0], targets[1]._replace(normals=None)])
    with pytest.raises(ValueError, match="normal deltas, but the mesh has no normals"):
        client.upload(*mesh[:3], morph_targets=targets)
    mesh_id = client.upload(*mesh[:3], normals=mesh[3], morph_targets=targets)
    palette = random_palette(rng, JOINTS)
    with pytest.raises(skinserve.SkinserveError, match="target 10 is not below the mesh's "
                       "morph_target_count 10") as e:
        client.skin(mesh_id, palette, morph_weights={10: 0.5})
    assert e.value.code.name == "INVALID_ARGUMENT"
    with pytest.raises(ValueError, match="weight nan of target 2 must be finite"):
        client.skin(mesh_id, palette, morph_weights={2: float("nan")})
    crowd = np.stack([palette, palette])
    with pytest.raises(ValueError, match="3 per-instance entries, but the frame is a crowd "
                       "of 2"):
        client.skin(mesh_id, crowd, morph_weights=[{}, {}, {}])
    with pytest.raises(ValueError, match="morph_weights: 1 entries, expected one per palette"):
        list(client.stream(mesh_id, [palette, palette], morph_weights=[{}]))
