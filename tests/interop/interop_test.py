"""Interop: a client nobody here wrote. Debian's python3-grpcio talks to the real skinserve
binary through stubs generated from our .proto at test time, and every frame is checked
against a float64 numpy evaluation of the paper's equations 3 and 4.

usage: interop_test.py SKINSERVE_BINARY PROTO_DIR
"""
import os
import signal
import subprocess
import sys
import tempfile
import time

import numpy as np


def generate_stubs(proto_dir, out_dir):
    from grpc_tools import protoc
    for proto in ("skinserve/v1/skinning.proto",):
        code = protoc.main(["protoc", f"-I{proto_dir}", f"--python_out={out_dir}",
                            f"--grpc_python_out={out_dir}", os.path.join(proto_dir, proto)])
        if code != 0:
            raise RuntimeError(f"protoc failed on {proto}")
    sys.path.insert(0, out_dir)


def wait_for_port(port_file, server, seconds=120):
    """The port a server started on 127.0.0.1:0 wrote to --port-file once serving."""
    deadline = time.time() + seconds
    while not (os.path.exists(port_file) and os.path.getsize(port_file) > 0):
        if server.poll() is not None:
            sys.exit(f"interop: skinserve exited with {server.returncode} before serving")
        if time.time() > deadline:
            server.kill()
            sys.exit(f"interop: skinserve wrote no port within {seconds} s")
        time.sleep(0.05)
    with open(port_file) as f:
        return int(f.read())


def random_mesh(rng, vertices, influences, joints):
    positions = rng.uniform(-2, 2, size=(vertices, 3)).astype(np.float32)
    normals = rng.normal(size=(vertices, 3))
    normals = (normals / np.linalg.norm(normals, axis=1, keepdims=True)).astype(np.float32)
    joint_ids = rng.integers(0, joints, size=(vertices, influences)).astype(np.uint16)
    weights = rng.uniform(0.05, 1, size=(vertices, influences))
    weights = (weights / weights.sum(axis=1, keepdims=True)).astype(np.float32)
    return positions, normals, joint_ids, weights


def random_palette(rng, joints):
    palette = np.zeros((joints, 3, 4))
    for j in range(joints):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))  # an orthonormal basis
        palette[j, :, :3] = q * rng.uniform(0.9, 1.1)
        palette[j, :, 3] = rng.uniform(-0.5, 0.5, size=3)
    return palette.astype(np.float32)


def reference(positions, normals, joint_ids, weights, palette):
    """Equations 3 and 4 in float64, vectorised over vertices."""
    m = np.einsum("vi,virc->vrc", weights.astype(np.float64),
                  palette.astype(np.float64)[joint_ids])
    p = np.einsum("vrc,vc->vr", m[:, :, :3], positions.astype(np.float64)) + m[:, :, 3]
    n = np.einsum("vrc,vc->vr", m[:, :, :3], normals.astype(np.float64))
    return p, n / np.linalg.norm(n, axis=1, keepdims=True)


def upload(pb, stub, positions, normals, joint_ids, weights, joints):
    def requests():
        header = pb.MeshHeader(vertex_count=len(positions), influences=joint_ids.shape[1],
                               joint_count=joints, has_normals=True)
        yield pb.UploadMeshRequest(header=header)
        for kind, array in ((pb.MESH_ARRAY_POSITIONS, positions), (pb.MESH_ARRAY_NORMALS, normals),
                            (pb.MESH_ARRAY_JOINTS, joint_ids), (pb.MESH_ARRAY_WEIGHTS, weights)):
            flat = array.reshape(-1)
            step = (1 << 20) // flat.itemsize
            for offset in range(0, len(flat), step):
                chunk = flat[offset:offset + step].astype(flat.dtype.newbyteorder("<"))
                yield pb.UploadMeshRequest(chunk=pb.MeshChunk(array=kind, offset=offset,
                                                              data=chunk.tobytes()))
    return stub.UploadMesh(requests())


def main():
    binary, proto_dir = sys.argv[1], sys.argv[2]
    out_dir = tempfile.mkdtemp(prefix="skinserve-interop-")
    generate_stubs(proto_dir, out_dir)
    import grpc
    from skinserve.v1 import skinning_pb2 as pb
    from skinserve.v1 import skinning_pb2_grpc as pb_grpc

    port_file = os.path.join(out_dir, "port")
    server = subprocess.Popen([binary, "--listen", "127.0.0.1:0", "--port-file", port_file,
                               "--log-level", "warn"])
    port = wait_for_port(port_file, server)
    failures = 0
    try:
        channel = grpc.insecure_channel(f"127.0.0.1:{port}")
        # grpc.health.v1.Health/Check by hand: an empty request; SERVING is field 1 = 1.
        # (Stubs generated for the "grpc" proto package would shadow the grpc module.)
        check = channel.unary_unary("/grpc.health.v1.Health/Check",
                                    request_serializer=lambda _: b"",
                                    response_deserializer=lambda data: data)
        # The port file is written once the server is SERVING: one check must say so.
        if check(None, timeout=30) != b"\x08\x01":
            raise RuntimeError("server wrote its port file but is not SERVING")

        stub = pb_grpc.SkinningStub(channel)
        rng = np.random.default_rng(7)
        joints, vertices, influences = 77, 20011, 3
        mesh = random_mesh(rng, vertices, influences, joints)
        info = upload(pb, stub, *mesh, joints)
        print(f"uploaded {info.mesh_id[:16]}...: {info.vertex_count} vertices")

        backends = [b.id for b in stub.ListBackends(pb.ListBackendsRequest()).backends
                    if b.available and b.id != "passthrough"]
        for backend in backends:
            palettes = [random_palette(rng, joints) for _ in range(4)]
            requests = (pb.SkinRequest(mesh_id=info.mesh_id, backend=backend, frame=f,
                                       palette=palettes[f].astype("<f4").tobytes(),
                                       want_normals=True) for f in range(len(palettes)))
            got = {}
            for part in stub.StreamSkin(requests):
                if part.HasField("error"):
                    raise RuntimeError(f"{backend} frame {part.frame}: {part.error.message}")
                p, n = got.setdefault(part.frame, (np.full((vertices, 3), np.nan),
                                                   np.full((vertices, 3), np.nan)))
                rows = slice(part.first_vertex, part.first_vertex + part.vertex_count)
                p[rows] = np.frombuffer(part.positions, dtype="<f4").reshape(-1, 3)
                n[rows] = np.frombuffer(part.normals, dtype="<f4").reshape(-1, 3)
            worst_p = worst_n = 0.0
            for f, palette in enumerate(palettes):
                want_p, want_n = reference(*mesh, palette)
                # np.max, not max(): a NaN (a vertex no part delivered, or a NaN result)
                # must fail the check, and Python's max(x, nan) returns x.
                worst_p = float(np.max([worst_p, np.max(np.abs(got[f][0] - want_p))]))
                worst_n = float(np.max([worst_n, np.max(np.abs(got[f][1] - want_n))]))
            # Tolerance: float32 rounding of |M p| <= ~1.1 * 2 * sqrt(3) + 0.5, and unit normals.
            ok = len(got) == len(palettes) and worst_p <= 1e-4 and worst_n <= 1e-5 \
                and not np.isnan(worst_p) and not np.isnan(worst_n)
            failures += 0 if ok else 1
            print(f"{backend:<16} frames {len(got)}  max |dp| {worst_p:.2e}  max |dn| {worst_n:.2e}"
                  f"  {'ok' if ok else 'MISMATCH'}")
        if len(backends) < 6:
            print(f"expected 6 computing backends, got {backends}")
            failures += 1
    finally:
        server.send_signal(signal.SIGTERM)
        code = server.wait(timeout=30)
        if code != 0:
            print(f"server exited with {code}")
            failures += 1
    print(f"{len(backends) - min(failures, len(backends))} passed, {failures} failed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
