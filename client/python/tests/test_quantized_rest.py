"""The quantized rest stream asked for at upload (rest_encoding) through a real server:
the mesh stores under its own id, and frames on simd and serial match the float64
reference of the original floats within the stream's error bound; an unknown encoding is
refused on the client naming the parameter, a mesh with morph targets by the server. A
mesh's tangents come from every backend that reads the stream.

Tolerance: the bound docs/backends/quantized-rest.md states, per vertex and axis r: the
position's half step through the blended matrix, sum_k |M_rk| * step_k / 2 (step_k = the
box's extent / 65535), plus each stored weight's error (< 1 step: 1/65535 or 1/255) times
|(M_i - M_last) (p, 1)|_r, plus float32's 1e-4. Normals, n' = A n / |A n| with A the
blended 3x3: twice the relative error of A n, (|A| |dn| + |dA|) / |A n|, where |dn| <=
sqrt(3) / 65534 (snorm16) and |dA| <= sum_i |M_i - M_last| / steps (Frobenius norms),
plus 1e-5."""
import asyncio

import numpy as np
import pytest

import skinserve
from reference import random_mesh, random_palette, skin
from test_tangents import random_tangents, skin_tangents

STEPS = {"quantized16": 65535, "quantized8-weights": 255}


def stated_bound(positions, joint_ids, weights, palette, encoding):
    """Per vertex and axis: the bound of the quantized stream against the original floats."""
    p = positions.astype(np.float64)
    m = palette.astype(np.float64)
    step = (p.max(axis=0) - p.min(axis=0)) / 65535
    blended = np.einsum("vi,virc->vrc", weights.astype(np.float64), m[joint_ids])
    bound = np.einsum("vrk,k->vr", np.abs(blended[:, :, :3]), step / 2)
    ph = np.hstack([p, np.ones((len(p), 1))])
    last = m[joint_ids[:, -1]]
    for i in range(joint_ids.shape[1] - 1):
        diff = np.einsum("vrc,vc->vr", m[joint_ids[:, i]] - last, ph)
        bound += np.abs(diff) / STEPS[encoding]
    return bound + 1e-4


def stated_normal_bound(normals, joint_ids, weights, palette, encoding):
    """Per vertex: the bound on a renormalised normal's error (any component)."""
    m = palette.astype(np.float64)[:, :, :3]
    blended = np.einsum("vi,virc->vrc", weights.astype(np.float64), m[joint_ids])
    a_n = np.linalg.norm(np.einsum("vrc,vc->vr", blended, normals.astype(np.float64)), axis=1)
    d_a = sum(np.linalg.norm(m[joint_ids[:, i]] - m[joint_ids[:, -1]], axis=(1, 2))
              for i in range(joint_ids.shape[1] - 1)) / STEPS[encoding]
    d_n = np.sqrt(3) / 65534
    return (2 * (np.linalg.norm(blended, axis=(1, 2)) * d_n + d_a) / a_n + 1e-5)[:, None]


@pytest.mark.parametrize("encoding", ["quantized16", "quantized8-weights"])
def test_a_quantized_upload_skins_within_its_bound(client, rng, encoding):
    positions, joint_ids, weights, normals = random_mesh(rng, 2000, 3, 20)
    plain = client.upload(positions, joint_ids, weights, normals=normals)
    quantized = client.upload(positions, joint_ids, weights, normals=normals,
                              rest_encoding=encoding)
    assert quantized != plain  # the encoding is content
    palette = random_palette(rng, 20)
    want_p, want_n = skin(positions, joint_ids, weights, normals, palette)
    bound = stated_bound(positions, joint_ids, weights, palette, encoding)
    normal_bound = stated_normal_bound(normals, joint_ids, weights, palette, encoding)
    for backend in ("simd", "simd-openmp", "serial"):
        got_p, got_n = client.skin(quantized, palette, backend=backend, want_normals=True)
        assert float(np.max(np.abs(got_p - want_p) / bound)) <= 1.0, backend
        assert float(np.max(np.abs(got_n - want_n) / normal_bound)) <= 1.0, backend
    # Stored quantized: the answer is the decoded mesh's, not the float mesh's.
    float_p = client.skin(plain, palette, backend="simd")
    assert float(np.max(np.abs(client.skin(quantized, palette, backend="simd") - float_p))) > 1e-6


def test_a_quantized_meshs_tangents_come_from_every_backend(client, rng):
    """Tangents in the stream (xyz snorm16 as the normals, w the handedness): the backends
    that read the integers (simd, simd-openmp, opencl, opencl-zerocopy) and one that skins
    the floats they decode to (serial) answer them within the normals' bound of the float64
    reference on the original floats, w exactly the rest tangent's."""
    positions, joint_ids, weights, normals = random_mesh(rng, 2000, 3, 20)
    tangents = random_tangents(rng, normals)
    mesh = client.upload(positions, joint_ids, weights, normals=normals, tangents=tangents,
                         rest_encoding="quantized16")
    palette = random_palette(rng, 20)
    want_t = skin_tangents(tangents, joint_ids, weights, palette)
    bound = stated_normal_bound(tangents[:, :3], joint_ids, weights, palette, "quantized16")
    for backend in ("simd", "simd-openmp", "opencl", "opencl-zerocopy", "serial"):
        _, _, got_t = client.skin(mesh, palette, backend=backend, want_normals=True,
                                  want_tangents=True)
        assert got_t.shape == (2000, 4), backend
        assert float(np.max(np.abs(got_t[:, :3] - want_t[:, :3]) / bound)) <= 1.0, backend
        assert np.array_equal(got_t[:, 3], tangents[:, 3]), backend


def test_the_async_client_asks_for_it_too(server, rng):
    positions, joint_ids, weights, _ = random_mesh(rng, 300, 2, 8)

    async def run():
        async with skinserve.AsyncClient(server.target) as c:
            plain = await c.upload(positions, joint_ids, weights)
            quantized = await c.upload(positions, joint_ids, weights, rest_encoding="quantized16")
            return plain, quantized

    plain, quantized = asyncio.run(run())
    assert plain != quantized


def test_bad_rest_encodings_are_refused(client, rng):
    positions, joint_ids, weights, normals = random_mesh(rng, 50, 2, 4)
    with pytest.raises(ValueError, match=r"rest_encoding: 'quantized4', expected one of "
                                         r"float32, quantized16, quantized8-weights"):
        client.upload(positions, joint_ids, weights, rest_encoding="quantized4")
    target = skinserve.MorphTarget(np.array([0, 3], dtype=np.uint32),
                                   np.full((2, 3), 0.1, dtype=np.float32))
    with pytest.raises(skinserve.SkinserveError, match="quantized rest stream carries no morph"):
        client.upload(positions, joint_ids, weights, morph_targets=[target],
                      rest_encoding="quantized16")
