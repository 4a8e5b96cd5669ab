"""Memory shared with a skinserve on the same host (the same-host data plane): the
server skins straight into it, and answers are NumPy arrays that view it (no copy).

    with skinserve.SharedMemoryRegion(64 << 20) as region:
        client.register_region(region)
        vertices = client.skin(mesh_id, palette, region=region)  # views the region
"""
import mmap
import os
import threading
from typing import Any, Optional

_ALIGNMENT = 64  # offsets in a region are multiples of this (the wire contract)
_counter = iter(range(1 << 62))
_counter_lock = threading.Lock()


def round_up(n: int) -> int:
    return (n + _ALIGNMENT - 1) // _ALIGNMENT * _ALIGNMENT


def frame_bytes(vertices: int, instances: int, bytes_per_value: int, normals: bool,
                tangents: bool = False) -> int:
    """Bytes one frame takes in a region: every instance's positions, then (from the next
    multiple of 64) their normals, then (from the next one) their tangents, 4 values a
    vertex; rounded up so that frames can follow each other."""
    array = vertices * 3 * bytes_per_value * max(instances, 1)
    end = round_up(array) + array if normals else array
    if tangents:
        end = round_up(end) + vertices * 4 * bytes_per_value * max(instances, 1)
    return round_up(end)


class SharedMemoryRegion:
    """A file of `byte_size` bytes in `directory` (the server's --shm-dir; /dev/shm holds
    POSIX shared-memory objects), created, mapped, and removed again by close().

    `key` is the file's name (default: a name unique to this process); `name` is set by
    Client.register_region to the name the server knows it by.
    """

    def __init__(self, byte_size: int, key: Optional[str] = None,
                 directory: str = "/dev/shm") -> None:
        if byte_size <= 0:
            raise ValueError(f"byte_size: {byte_size}, expected > 0")
        if key is None:
            with _counter_lock:
                key = f"skinserve-py-{os.getpid()}-{next(_counter)}"
        if "/" in key.lstrip("/") or key.strip("/") in ("", ".", ".."):
            raise ValueError(f"key: {key!r}, expected one file name")
        self.key = key.lstrip("/")
        self.path = os.path.join(directory, self.key)
        self.byte_size = byte_size
        self.name: Optional[str] = None
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o660)
        try:
            os.ftruncate(fd, byte_size)
            # Allocated now, as the C++ client's regions are: a file system too small for
            # the region (a container's /dev/shm) says so here, not at the server's first frame.
            try:
                os.posix_fallocate(fd, 0, byte_size)
            except OSError as e:
                raise OSError(e.errno, f"cannot allocate {self.path} ({byte_size} bytes): "
                              f"{e.strerror}") from e
            self._map = mmap.mmap(fd, byte_size)
        except BaseException:
            os.unlink(self.path)
            raise
        finally:
            os.close(fd)
        self.buffer: Optional[memoryview] = memoryview(self._map)

    def close(self) -> None:
        """Unmaps and removes the file. Arrays that still view the region keep it mapped
        until they are gone (NumPy holds the buffer)."""
        if self.buffer is None:
            return
        self.buffer.release()
        self.buffer = None
        try:
            self._map.close()
        except BufferError:  # an array still views it: the mapping goes with the last one
            pass
        try:
            os.unlink(self.path)
        except FileNotFoundError:
            pass

    def __enter__(self) -> "SharedMemoryRegion":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
