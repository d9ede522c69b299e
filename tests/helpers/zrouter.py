"""A real Zenoh router process (``python -m arduinobot.service.router``), `arduinobot serve` behind
it, configs derived from the shipped templates, and a throwaway test CA."""

from __future__ import annotations

import datetime
import ipaddress
import json
import signal
import subprocess
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from .procs import REPO, launch_all, stop_process
from .serve import Server
from .serve import launch_serves as _launch

SECURITY = REPO / "src" / "arduinobot" / "service" / "security"

#: what ``python -m arduinobot.service.router`` logs once it listens ("router <zid> ready, ...")
READY = " ready"


@dataclass
class Router:
    """A running ``python -m arduinobot.service.router``; :meth:`restart` starts it again with the
    same arguments (same port)."""

    proc: subprocess.Popen
    endpoint: str
    argv: list[str]
    lines: list[str] = field(default_factory=list)

    @property
    def zid(self) -> str:
        line = next(ln for ln in self.lines if READY in ln)
        return line.split("router ", 1)[1].split(" ", 1)[0]

    def stop(self, sig: int = signal.SIGINT, timeout: float = 10.0) -> int:
        return stop_process(self.proc, sig, timeout)

    def restart(self) -> Router:
        self.stop(signal.SIGKILL)
        return _launch_router(self.argv, self.endpoint)


def start_router(endpoint: str, *, config: Path | None = None) -> Router:
    """Start a router listening on ``endpoint`` (over the config's listen endpoints)."""
    argv = [sys.executable, "-m", "arduinobot.service.router", "--listen", endpoint]
    if config is not None:
        argv += ["--config", str(config)]
    return _launch_router(argv, endpoint)


def _launch_router(argv: list[str], endpoint: str, timeout: float = 20.0) -> Router:
    (p,) = launch_all([argv], ready=READY, what="the router", timeout=timeout)
    return Router(p.proc, endpoint, p.argv, p.lines)


def launch_serves(arg_lists: Sequence[Sequence[str]], *, timeout: float = 120.0) -> list[Server]:
    """`arduinobot serve` with exactly these arguments (serve.start_servers adds a
    loopback listener; a service behind a secured router must have none)."""
    return _launch(arg_lists, timeout=timeout)


def derive_config(template: str | Path, out: Path, settings: Mapping[str, object]) -> Path:
    """``template`` (a zenoh JSON5 file) with each ``"a/b/c": value`` set, written to
    ``out`` as JSON."""
    import zenoh
    cfg = zenoh.Config.from_file(str(template))
    for key, value in settings.items():
        cfg.insert_json5(key, json.dumps(value))
    out.write_text(str(cfg))
    return out


@dataclass(frozen=True)
class Pki:
    """A throwaway CA and a certificate it signed for 127.0.0.1 / localhost (PEM files)."""

    ca: Path
    cert: Path
    key: Path
    other_ca: Path  #: a CA that signed nothing here: trusting it is trusting the wrong one


def make_test_pki(folder: Path) -> Pki:
    """Generate the CA, the router's key and certificate into ``folder`` (valid 1 day)."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    now = datetime.datetime.now(datetime.timezone.utc)
    pem = serialization.Encoding.PEM

    def ca(name: str) -> tuple[x509.Certificate, ec.EllipticCurvePrivateKey]:
        key = ec.generate_private_key(ec.SECP256R1())
        subject = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)])
        cert = (x509.CertificateBuilder().subject_name(subject).issuer_name(subject)
                .public_key(key.public_key()).serial_number(x509.random_serial_number())
                .not_valid_before(now - datetime.timedelta(minutes=5))
                .not_valid_after(now + datetime.timedelta(days=1))
                .add_extension(x509.BasicConstraints(ca=True, path_length=None), critical=True)
                .sign(key, hashes.SHA256()))
        return cert, key

    ca_cert, ca_key = ca("arduinobot test CA")
    other_cert, _ = ca("another CA")
    key = ec.generate_private_key(ec.SECP256R1())
    cert = (x509.CertificateBuilder()
            .subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "localhost")]))
            .issuer_name(ca_cert.subject).public_key(key.public_key())
            .serial_number(x509.random_serial_number())
            .not_valid_before(now - datetime.timedelta(minutes=5))
            .not_valid_after(now + datetime.timedelta(days=1))
            .add_extension(x509.SubjectAlternativeName(
                [x509.DNSName("localhost"), x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]),
                critical=False)
            .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
            .sign(ca_key, hashes.SHA256()))
    folder.mkdir(parents=True, exist_ok=True)
    pki = Pki(folder / "ca.pem", folder / "router.pem", folder / "router-key.pem",
                  folder / "other-ca.pem")
    pki.ca.write_bytes(ca_cert.public_bytes(pem))
    pki.other_ca.write_bytes(other_cert.public_bytes(pem))
    pki.cert.write_bytes(cert.public_bytes(pem))
    pki.key.write_bytes(key.private_bytes(pem, serialization.PrivateFormat.PKCS8,
                                          serialization.NoEncryption()))
    pki.key.chmod(0o600)
    return pki
