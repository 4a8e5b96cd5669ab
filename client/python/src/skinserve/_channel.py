"""The channel settings both clients share: options (balancing, flow control, keepalive)
and TLS credentials."""
from typing import Any, List, Optional, Tuple, Union

import grpc

STREAM_WINDOW_BYTES = 4 << 20
Option = Tuple[str, Union[int, str]]


def options(keepalive: Optional[float], keepalive_timeout: float,
            tls_server_name: Optional[str]) -> List[Option]:
    # Flow control as the C++ library's MakeChannel: a fixed 4 MiB receive window per
    # stream, BDP probing off (with probing, crowd frames of several 1 MiB parts stalled
    # now and then; docs/client-library.md, "Channels").
    out: List[Option] = [("grpc.service_config",
                          '{"loadBalancingConfig": [{"round_robin": {}}]}'),
                         ("grpc.http2.bdp_probe", 0),
                         ("grpc.http2.lookahead_bytes", STREAM_WINDOW_BYTES)]
    if keepalive:
        # Pings also while this side sends nothing (gRPC stops after two otherwise).
        out += [("grpc.keepalive_time_ms", int(keepalive * 1000)),
                ("grpc.keepalive_timeout_ms", int(keepalive_timeout * 1000)),
                ("grpc.http2.max_pings_without_data", 0),
                ("grpc.keepalive_permit_without_calls", 0)]
    if tls_server_name:
        out.append(("grpc.ssl_target_name_override", tls_server_name))
    return out


def _read(option: str, path: str) -> bytes:
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as e:
        raise ValueError(f"{option} '{path}': cannot read the file: {e.strerror}") from None
    if b"-----BEGIN " not in data:
        raise ValueError(f"{option} '{path}': no PEM block (-----BEGIN ...) in the file")
    return data


def credentials(tls_ca: Optional[str], tls_cert: Optional[str], tls_key: Optional[str],
                tls_server_name: Optional[str]) -> Any:
    """grpc.ChannelCredentials for TLS, or None for plaintext; checks the combination."""
    if tls_ca is None and (tls_cert or tls_key or tls_server_name):
        raise ValueError("tls_cert, tls_key and tls_server_name need tls_ca: the CA that "
                         "signed the server's certificate")
    if bool(tls_cert) != bool(tls_key):
        raise ValueError(f"tls_cert and tls_key go together: tls_cert is {tls_cert!r}, "
                         f"tls_key {tls_key!r}")
    if tls_ca is None:
        return None
    return grpc.ssl_channel_credentials(
        root_certificates=_read("tls_ca", tls_ca),
        private_key=_read("tls_key", tls_key) if tls_key else None,
        certificate_chain=_read("tls_cert", tls_cert) if tls_cert else None)
