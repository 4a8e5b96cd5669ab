"""Wrong dtypes and shapes: a ValueError naming the array, before anything is sent (the
client points at a port nobody listens on: any call would fail with UNAVAILABLE)."""
import socket

import numpy as np
import pytest

import skinserve
from reference import random_mesh, random_palette


@pytest.fixture
def offline():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with skinserve.Client(f"127.0.0.1:{port}") as c:
        yield c


@pytest.fixture
def mesh(rng):
    return dict(zip(("positions", "joints", "weights", "normals"),
                    random_mesh(rng, 50, 2, 10)))


@pytest.mark.parametrize("name,bad,message", [
    ("positions", lambda m: m["positions"].astype(np.float64), "positions: dtype float64"),
    ("positions", lambda m: m["positions"][:, :2], r"positions: shape \(50, 2\)"),
    ("positions", lambda m: m["positions"].tolist(), "positions: expected a numpy.ndarray"),
    ("joints", lambda m: m["joints"].astype(np.int32), "joints: dtype int32"),
    ("joints", lambda m: m["joints"][:40], r"joints: shape \(40, 2\)"),
    ("joints", lambda m: np.zeros((50, 9), np.uint16), r"joints: shape \(50, 9\)"),
    ("weights", lambda m: m["weights"].astype(np.float16), "weights: dtype float16"),
    ("weights", lambda m: m["weights"][:, :1], r"weights: shape \(50, 1\)"),
    ("normals", lambda m: m["normals"].astype(np.float64), "normals: dtype float64"),
    ("normals", lambda m: m["normals"][:10], r"normals: shape \(10, 3\)"),
])
def test_upload_names_the_bad_array(offline, mesh, name, bad, message):
    mesh[name] = bad(mesh)
    with pytest.raises(ValueError, match=message):
        offline.upload(**mesh)


def test_palette_checks(offline, rng):
    with pytest.raises(ValueError, match="palette: dtype float64"):
        offline.skin("m", random_palette(rng, 4).astype(np.float64))
    with pytest.raises(ValueError, match=r"palette: shape \(4, 4, 4\)"):
        offline.skin("m", np.zeros((4, 4, 4), np.float32))
    good = random_palette(rng, 4)
    with pytest.raises(ValueError, match=r"palettes\[2\]: dtype float64"):
        list(offline.stream("m", [good, good, good.astype(np.float64)]))
    with pytest.raises(ValueError, match="encoding: 'int8'"):
        offline.skin("m", good, encoding="int8")
    with pytest.raises(ValueError, match=r"palette: shape \(0, 4, 3, 4\), a crowd of 0"):
        offline.skin("m", np.zeros((0, 4, 3, 4), np.float32))
    with pytest.raises(ValueError, match=r"palette: shape \(2, 4, 3, 5\)"):
        offline.skin("m", np.zeros((2, 4, 3, 5), np.float32))


def test_palette_joint_count_of_a_known_mesh(server, rng):
    with skinserve.Client(server.target) as client:
        mesh_id = client.upload(*random_mesh(rng, 50, 2, 10))
        with pytest.raises(ValueError, match="palette: 9 matrices, the mesh has 10 joints"):
            client.skin(mesh_id, random_palette(rng, 9))


def test_joint_count_below_the_ids_used(offline, mesh):
    with pytest.raises(ValueError, match="joint_count: 5, expected an int >= 10"):
        offline.upload(**mesh, joint_count=5)
