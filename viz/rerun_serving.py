"""Where a served recording can be watched (`--rerun-serve [PORT] [--rerun-serve-host ADDRESS]`): Rerun's gRPC data
server on ADDRESS (127.0.0.1 unless asked: this machine only) at a port chosen free here and read back, so the
address printed and handed to the web viewer is the one the server listens on; and Rerun's web viewer page (HTML,
JS, Wasm; no data) on PORT. Rerun's web server takes no address: its page is reachable on every interface, the
data only where the gRPC server listens."""
from __future__ import annotations

import errno
import ipaddress
import socket
from dataclasses import dataclass

LOCALHOST = "127.0.0.1"
ANY = ("0.0.0.0", "::")


def check_serve_host(host: str) -> str:
    """`host` as an IP address the data server can bind ("localhost" is 127.0.0.1); ValueError naming it else."""
    if host == "localhost":
        return LOCALHOST
    try:
        return str(ipaddress.ip_address(host))
    except ValueError:
        raise ValueError(f"--rerun-serve-host {host}: not an IP address of this machine (e.g. 192.168.1.20, "
                         "or 0.0.0.0 for every interface)") from None


def free_port(host: str, port: int = 0) -> int:
    """`port` (0: one the system picks) after checking it can be bound on `host` now; OSError naming the address
    when it is in use or `host` is not an address of this machine. (Rerun's gRPC sink reports neither.)"""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:
        try:
            probe.bind((host, port))
        except OSError as exc:
            what = "is already in use" if exc.errno == errno.EADDRINUSE else f"cannot be listened on ({exc.strerror})"
            raise OSError(f"{host}:{port} {what}") from None
        return probe.getsockname()[1]


@dataclass(frozen=True)
class ServedAt:
    """The data server's `host` and `grpc_port`, the web viewer's `web_port`."""

    host: str
    grpc_port: int
    web_port: int

    @property
    def local(self) -> bool:
        return ipaddress.ip_address(self.host).is_loopback

    def _shown_host(self) -> str:
        """The address another machine opens (this machine's name when serving on every interface)."""
        return socket.getfqdn() if self.host in ANY else f"[{self.host}]" if ":" in self.host else self.host

    @property
    def data_url(self) -> str:
        """What the viewer connects to (`rerun URL` in a terminal opens it in the native viewer)."""
        return f"rerun+http://{LOCALHOST if self.local else self._shown_host()}:{self.grpc_port}/proxy"

    @property
    def web_url(self) -> str:
        """The web viewer's page, connected to the data."""
        return f"http://{'localhost' if self.local else self._shown_host()}:{self.web_port}/?url={self.data_url}"

    def lines(self) -> list[str]:
        """What the command prints: where to watch, who can, and (not local) the warning."""
        if self.local:
            return [f"rerun     web viewer at {self.web_url}",
                    f"rerun     this machine only (data on {LOCALHOST}:{self.grpc_port}; native viewer: rerun {self.data_url}); "
                    "--rerun-serve-host ADDRESS serves to other machines"]
        where = "every interface" if self.host in ANY else self.host
        return [f"rerun     web viewer at {self.web_url} (open it from another machine; native viewer: rerun {self.data_url})",
                f"warning   the stream (cameras, hands, pressure) is served unauthenticated on {where}, port "
                f"{self.grpc_port}: anyone who can reach it can watch"]
