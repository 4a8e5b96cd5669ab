"""TLS, mutual TLS, the authorization policy and the call limits through the Python
clients (blocking and asyncio), against a real server with certificates made here (scripts/make-dev-certs.sh)."""
import asyncio
import os
import signal
import subprocess
import time

import grpc
import pytest

import skinserve
from reference import POSITION_TOLERANCE, max_error, random_mesh, random_palette, skin

JOINTS = 12


def _root():
    root = os.environ.get("SKINSERVE_SOURCE_DIR")
    if not root:
        pytest.fail("set SKINSERVE_SOURCE_DIR to the repository (scripts/make-dev-certs.sh)")
    return root


@pytest.fixture(scope="module")
def certs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("certs")
    subprocess.run(["bash", os.path.join(_root(), "scripts", "make-dev-certs.sh"), str(folder),
                    "operator", "renderer"], check=True, stdout=subprocess.DEVNULL)
    return folder


def start(binary, folder, *args):
    """skinserve on a port the kernel picks, two quick backends; (process, target) once it
    serves (it writes the port file then)."""
    port_file = folder / "port"
    process = subprocess.Popen(
        [binary, "--listen", "127.0.0.1:0", "--port-file", str(port_file), "--threads", "1",
         "--log-level", "warn", "--backends", "sse,passthrough", "--default-backend", "sse",
         *args])
    deadline = time.time() + 60
    while not (port_file.exists() and port_file.read_text().strip()):
        assert process.poll() is None, "skinserve exited"
        assert time.time() < deadline, "skinserve wrote no port in 60 s"
        time.sleep(0.05)
    return process, f"127.0.0.1:{port_file.read_text().strip()}"


@pytest.fixture(scope="module")
def tls_server(binary, certs, tmp_path_factory):
    """Mutual TLS with deploy/authz-policy.json."""
    process, target = start(
        binary, tmp_path_factory.mktemp("tls-server"),
        "--tls-cert", str(certs / "server.pem"), "--tls-key", str(certs / "server.key"),
        "--tls-client-ca", str(certs / "ca.pem"),
        "--authz-policy", os.path.join(_root(), "deploy", "authz-policy.json"))
    yield target
    process.send_signal(signal.SIGTERM)
    assert process.wait(timeout=60) == 0


def client_as(target, certs, who=None, **kwargs):
    tls = {"tls_ca": str(certs / "ca.pem")}
    if who:
        tls.update(tls_cert=str(certs / f"{who}.pem"), tls_key=str(certs / f"{who}.key"))
    return skinserve.Client(target, timeout=5, **tls, **kwargs)


def test_the_right_certificate_works(tls_server, certs, rng):
    with client_as(tls_server, certs, "renderer") as client:
        mesh = random_mesh(rng, 2001, 2, JOINTS)
        mesh_id = client.upload(*mesh)
        palette = random_palette(rng, JOINTS)
        positions = client.skin(mesh_id, palette, backend="sse")
        assert max_error(positions, skin(*mesh, palette)[0]) <= POSITION_TOLERANCE
        palettes = [random_palette(rng, JOINTS) for _ in range(12)]
        for got, palette in zip(client.stream(mesh_id, palettes, backend="sse", window=4),
                                palettes):
            assert max_error(got, skin(*mesh, palette)[0]) <= POSITION_TOLERANCE


def test_the_async_client_speaks_mutual_tls(tls_server, certs, rng):
    mesh = random_mesh(rng, 2001, 2, JOINTS)
    palettes = [random_palette(rng, JOINTS) for _ in range(6)]

    async def main():
        async with skinserve.AsyncClient(tls_server, timeout=5, tls_ca=str(certs / "ca.pem"),
                                         tls_cert=str(certs / "renderer.pem"),
                                         tls_key=str(certs / "renderer.key")) as client:
            mesh_id = await client.upload(*mesh)
            single = await client.skin(mesh_id, palettes[0], backend="sse")
            return [single] + [f async for f in client.stream(mesh_id, palettes[1:],
                                                              backend="sse", window=2)]
    frames = asyncio.run(asyncio.wait_for(main(), timeout=60))
    assert len(frames) == len(palettes)
    for got, palette in zip(frames, palettes):
        assert max_error(got, skin(*mesh, palette)[0]) <= POSITION_TOLERANCE

    async def plaintext():
        async with skinserve.AsyncClient(tls_server, timeout=5) as client:
            await client.backends()
    with pytest.raises(skinserve.SkinserveError) as refused:
        asyncio.run(plaintext())
    assert refused.value.code == grpc.StatusCode.UNAVAILABLE, refused.value


def test_a_plaintext_client_is_refused(tls_server):
    with skinserve.Client(tls_server, timeout=5) as client:
        with pytest.raises(skinserve.SkinserveError) as refused:
            client.backends()
    assert refused.value.code == grpc.StatusCode.UNAVAILABLE, refused.value


def test_a_client_without_a_certificate_is_refused(tls_server, certs):
    with client_as(tls_server, certs) as client:
        with pytest.raises(skinserve.SkinserveError) as refused:
            client.backends()
    assert refused.value.code == grpc.StatusCode.UNAVAILABLE, refused.value


def test_the_server_name_is_checked(tls_server, certs):
    port = tls_server.rsplit(":", 1)[1]
    with client_as(f"localhost:{port}", certs, "renderer") as client:
        assert client.backends()
    with client_as(tls_server, certs, "renderer", tls_server_name="elsewhere.example") as client:
        with pytest.raises(skinserve.SkinserveError) as refused:
            client.backends()
    assert refused.value.code == grpc.StatusCode.UNAVAILABLE


def test_the_policy_allows_and_denies(tls_server, certs):
    with client_as(tls_server, certs, "renderer") as renderer:
        with pytest.raises(skinserve.SkinserveError) as denied:
            renderer.stats()
        assert denied.value.code == grpc.StatusCode.PERMISSION_DENIED
    with client_as(tls_server, certs, "operator") as operator:
        assert operator.stats()["compute_threads"] == 1


def test_unreadable_files_name_the_option(certs):
    with pytest.raises(ValueError, match="tls_ca '/nonexistent/ca.pem'"):
        skinserve.Client("127.0.0.1:1", tls_ca="/nonexistent/ca.pem")
    with pytest.raises(ValueError, match="tls_cert and tls_key go together"):
        skinserve.Client("127.0.0.1:1", tls_ca=str(certs / "ca.pem"),
                         tls_cert=str(certs / "renderer.pem"))


def freeze(process):
    """SIGSTOP, then wait until the kernel says the process stopped (delivery is
    asynchronous: without the wait it may still answer a call)."""
    process.send_signal(signal.SIGSTOP)
    deadline = time.monotonic() + 1
    while time.monotonic() < deadline:
        with open(f"/proc/{process.pid}/stat") as f:
            if f.read().rsplit(")", 1)[1].split()[0] == "T":
                return
        time.sleep(0.001)
    raise AssertionError("the server did not stop within 1 s of SIGSTOP")


def test_a_frozen_server_ends_calls_and_streams_in_time(binary, rng, tmp_path):
    """SIGSTOP: the server's kernel keeps the connection, nothing answers. A call ends at
    its timeout, a stream at its idle limit (keepalive off here)."""
    process, target = start(binary, tmp_path)
    try:
        with skinserve.Client(target, timeout=1, stream_idle_timeout=1, keepalive=None,
                              max_reconnects=0) as client:
            mesh = random_mesh(rng, 1001, 2, JOINTS)
            mesh_id = client.upload(*mesh)
            palettes = [random_palette(rng, JOINTS) for _ in range(400)]
            frames = client.stream(mesh_id, palettes, backend="sse", window=4)
            next(frames)
            freeze(process)
            started = time.monotonic()
            with pytest.raises(skinserve.SkinserveError) as idle:
                for _ in frames:
                    pass
            took = time.monotonic() - started
            assert idle.value.code == grpc.StatusCode.DEADLINE_EXCEEDED, idle.value
            assert took < 3, took
            started = time.monotonic()
            with pytest.raises(skinserve.SkinserveError) as late:
                client.backends()
            assert late.value.code == grpc.StatusCode.DEADLINE_EXCEEDED
            assert time.monotonic() - started < 3
    finally:
        process.send_signal(signal.SIGCONT)
        process.kill()
        process.wait()


def test_a_frozen_server_ends_async_calls_and_streams_in_time(binary, rng, tmp_path):
    """The same for AsyncClient: its stream's idle limit is its read loop's, not a thread."""
    process, target = start(binary, tmp_path)

    async def main():
        async with skinserve.AsyncClient(target, timeout=1, stream_idle_timeout=1,
                                         keepalive=None, max_reconnects=0) as client:
            mesh = random_mesh(rng, 1001, 2, JOINTS)
            mesh_id = await client.upload(*mesh)
            palettes = [random_palette(rng, JOINTS) for _ in range(400)]
            frames = client.stream(mesh_id, palettes, backend="sse", window=4)
            first = await frames.__anext__()
            assert max_error(first, skin(*mesh, palettes[0])[0]) <= POSITION_TOLERANCE
            freeze(process)
            started = time.monotonic()
            with pytest.raises(skinserve.SkinserveError) as idle:
                async for _ in frames:
                    pass
            took = time.monotonic() - started
            assert idle.value.code == grpc.StatusCode.DEADLINE_EXCEEDED, idle.value
            assert took < 3, took
            started = time.monotonic()
            with pytest.raises(skinserve.SkinserveError) as late:
                await client.backends()
            assert late.value.code == grpc.StatusCode.DEADLINE_EXCEEDED
            assert time.monotonic() - started < 3
    try:
        asyncio.run(asyncio.wait_for(main(), timeout=60))
    finally:
        process.send_signal(signal.SIGCONT)
        process.kill()
        process.wait()
