"""A real skinserve server for the tests: $SKINSERVE_BINARY on a free loopback port."""
import os
import shutil
import signal
import socket
import subprocess
import tempfile
import time

import grpc
import numpy as np
import pytest

import skinserve


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_serving(channel, deadline):
    # grpc.health.v1.Health/Check by hand: empty request, SERVING is field 1 = 1.
    check = channel.unary_unary("/grpc.health.v1.Health/Check",
                                request_serializer=lambda _: b"",
                                response_deserializer=lambda data: data)
    while time.time() < deadline:
        try:
            if check(None, timeout=2) == b"\x08\x01":
                return
        except grpc.RpcError:
            pass
        time.sleep(0.2)
    raise RuntimeError("skinserve never became SERVING")


class Server:
    """`unix_socket`: a Unix socket too, at `unix_target` (shared-memory regions are served
    there only: their owner is the client's process)."""

    def __init__(self, binary, *args, unix_socket=False):
        self.port = _free_port()
        self.target = f"127.0.0.1:{self.port}"
        self.socket_dir = tempfile.mkdtemp(prefix="skinserve-py-sock-") if unix_socket else None
        self.unix_target = f"unix:{self.socket_dir}/grpc.sock" if unix_socket else None
        listen = ",".join(t for t in (self.target, self.unix_target) if t)
        self._command = [binary, "--listen", listen, "--threads", "1", "--log-level", "warn",
                         *args]
        self._start()

    def _start(self):
        self.process = subprocess.Popen(self._command)
        with grpc.insecure_channel(self.target) as channel:
            _wait_serving(channel, time.time() + 120)

    def restart(self):
        """A new server process on the same address: everything uploaded is gone."""
        self.process.send_signal(signal.SIGTERM)
        assert self.process.wait(timeout=60) == 0
        self._start()

    def stop(self):
        self.process.send_signal(signal.SIGTERM)
        assert self.process.wait(timeout=60) == 0
        if self.socket_dir:
            shutil.rmtree(self.socket_dir, ignore_errors=True)


@pytest.fixture(scope="session")
def binary():
    path = os.environ.get("SKINSERVE_BINARY")
    if not path:
        pytest.fail("set SKINSERVE_BINARY to the skinserve server binary")
    return path


@pytest.fixture(scope="session")
def server(binary):
    s = Server(binary)
    yield s
    s.stop()


@pytest.fixture
def client(server):
    with skinserve.Client(server.target) as c:
        yield c


@pytest.fixture
def rng():
    return np.random.default_rng(15)


@pytest.fixture(scope="module")
def shm_dir():
    """A folder in /dev/shm for one test module's servers' regions (--shm-dir)."""
    path = tempfile.mkdtemp(prefix="skinserve-py-", dir="/dev/shm")
    yield path
    shutil.rmtree(path, ignore_errors=True)
