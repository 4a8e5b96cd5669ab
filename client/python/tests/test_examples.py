"""examples/ against a real server: each run as a script (as the documentation says), and
its answers checked against the float64 reference; the documentation shows them verbatim."""
import asyncio
import os
import runpy
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from reference import skin
from test_crowds_and_encodings import POSITION_TOLERANCE, check_instance

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
NAMES = ["blocking_client.py", "asyncio_client.py"]
SHOWN = NAMES + ["morph_client.py"]


@pytest.mark.parametrize("name", SHOWN)
def test_example_runs_as_a_script(server, name):
    done = subprocess.run([sys.executable, str(EXAMPLES / name), server.target],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "frames streamed" in done.stdout


@pytest.mark.parametrize("name", NAMES)
def test_example_answers_match_float64(server, name, monkeypatch):
    monkeypatch.syspath_prepend(str(EXAMPLES))  # asyncio_client imports blocking_client
    main = runpy.run_path(str(EXAMPLES / name))["main"]
    out = main(server.target)
    if asyncio.iscoroutine(out):
        out = asyncio.run(out)
    mesh = (out["positions"], out["joints"], out["weights"], None)

    def check(got, palette, encoding):
        check_instance(got, skin(*mesh, palette)[0], encoding, POSITION_TOLERANCE)

    assert out["single"].shape == (8, 3)
    check(out["single"], out["single_palette"], "float32")
    assert out["crowd"].shape == (3, 8, 3)
    for k, palette in enumerate(out["crowd_palettes"]):
        check(out["crowd"][k], palette, "float16")
    assert len(out["frames"]) == len(out["stream_palettes"]) == 5
    for got, palette in zip(out["frames"], out["stream_palettes"]):
        check(got, palette, "snorm16")
    for got, palette in zip(out.get("gathered", []), out["stream_palettes"]):
        check(got, palette, "float32")


def test_morph_example_answers_match_float64(server, monkeypatch):
    """Morphed in float64 here (rest + sum of weight x delta), then skinned in float64."""
    monkeypatch.syspath_prepend(str(EXAMPLES))  # morph_client imports blocking_client
    out = runpy.run_path(str(EXAMPLES / "morph_client.py"))["main"](server.target)

    def check(got, palette, weights):
        positions = out["positions"].astype(np.float64)
        for target, weight in weights.items():
            t = out["targets"][target]
            positions[t.indices] += weight * t.positions.astype(np.float64)
        want = skin(positions, out["joints"], out["weights"], None, palette)[0]
        check_instance(got, want, "float32", POSITION_TOLERANCE)

    check(out["single"], out["single_palette"], out["single_weights"])
    for k, palette in enumerate(out["crowd_palettes"]):
        check(out["crowd"][k], palette, out["crowd_weights"][k])
    assert len(out["frames"]) == 5
    for got, palette, weights in zip(out["frames"], out["stream_palettes"],
                                     out["stream_weights"]):
        check(got, palette, weights)


@pytest.mark.parametrize("name", SHOWN)
def test_documentation_shows_the_example_verbatim(name):
    source = os.environ.get("SKINSERVE_SOURCE_DIR")
    assert source, "set SKINSERVE_SOURCE_DIR to the repository"
    page = (Path(source) / "docs" / "client-library.md").read_text()
    shown = (EXAMPLES / name).read_text().strip() in page
    assert shown, f"examples/{name} is not in docs/client-library.md as it is in the file"
