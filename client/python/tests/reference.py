"""Random valid meshes and palettes, and linear blend skinning in float64."""
import numpy as np


def random_mesh(rng, vertices, influences, joints):
    positions = rng.uniform(-2, 2, size=(vertices, 3)).astype(np.float32)
    normals = rng.normal(size=(vertices, 3))
    normals = (normals / np.linalg.norm(normals, axis=1, keepdims=True)).astype(np.float32)
    joint_ids = rng.integers(0, joints, size=(vertices, influences)).astype(np.uint16)
    joint_ids[0, 0] = joints - 1  # the joint count is the largest id + 1
    weights = rng.uniform(0.05, 1, size=(vertices, influences))
    weights = (weights / weights.sum(axis=1, keepdims=True)).astype(np.float32)
    return positions, joint_ids, weights, normals


def random_palette(rng, joints):
    palette = np.zeros((joints, 3, 4))
    for j in range(joints):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        palette[j, :, :3] = q * rng.uniform(0.9, 1.1)
        palette[j, :, 3] = rng.uniform(-0.5, 0.5, size=3)
    return palette.astype(np.float32)


def skin(positions, joint_ids, weights, normals, palette):
    """v' = sum_i w_i M_i v (positions with w = 1, normals with w = 0, then renormalised)."""
    m = np.einsum("vi,virc->vrc", weights.astype(np.float64),
                  palette.astype(np.float64)[joint_ids])
    p = np.einsum("vrc,vc->vr", m[:, :, :3], positions.astype(np.float64)) + m[:, :, 3]
    if normals is None:
        return p, None
    n = np.einsum("vrc,vc->vr", m[:, :, :3], normals.astype(np.float64))
    return p, n / np.linalg.norm(n, axis=1, keepdims=True)


# float32 rounding of |M p| <= ~1.1 * 2 * sqrt(3) + 0.5 (a few ulp), and of unit normals.
POSITION_TOLERANCE = 1e-4
NORMAL_TOLERANCE = 1e-5


def max_error(got, want):
    return float(np.max(np.abs(got.astype(np.float64) - want)))  # NaN propagates: fails
