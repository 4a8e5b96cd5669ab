"""SkinserveError: how both clients report a failed call or frame."""
from typing import Any, List, Optional, Tuple

import grpc


class SkinserveError(Exception):
    """A call or a frame the server answered with an error: `code` (grpc.StatusCode), the
    server's own message, and the frame's number when a frame failed."""

    def __init__(self, code: Any, message: str, frame: Optional[int] = None) -> None:
        self.code, self.message, self.frame = code, message, frame
        where = f"frame {frame}: " if frame is not None else ""
        super().__init__(f"{where}{code.name}: {message}")


def status_code(value: int) -> Any:
    """The grpc.StatusCode of a FrameError.code (a google.rpc.Code value)."""
    for code in grpc.StatusCode:
        if code.value[0] == value:
            return code
    return grpc.StatusCode.UNKNOWN


_HINTS: List[Tuple[str, str]] = [  # gRPC's reasons for a failed connection, and the likely TLS cause
    ("Socket closed", "the server closed the connection at once: a TLS server refuses "
     "plaintext clients (give tls_ca), a mutual-TLS server refuses clients without a "
     "certificate (give tls_cert and tls_key)"),
    ("wrong version number", "the server does not speak TLS there (plaintext, or a unix: "
     "address): leave out tls_ca, tls_cert and tls_key"),
    ("certificate verify failed", "the server's certificate is not signed by the CA of tls_ca"),
]


def rpc_error(error: Any, frame: Optional[int] = None) -> SkinserveError:
    """A grpc.RpcError (or grpc.aio.AioRpcError) as a SkinserveError, with a hint for the
    usual TLS mistakes."""
    details: str = error.details() or ""
    if error.code() == grpc.StatusCode.UNAVAILABLE:
        for reason, hint in _HINTS:
            if reason in details:
                details = f"{details} (hint: {hint})"
                break
    return SkinserveError(error.code(), details, frame)
