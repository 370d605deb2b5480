"""People in the ledger are keys: runs and sign-offs signed with SSH signatures (``ssh-keygen -Y``).

Why SSH signatures (not Ed25519 keys of our own through ``cryptography``): auditors and agencies
already hold SSH keys and an SSH agent, often on hardware tokens, and already keep *allowed-signers*
files (``git`` commit signing uses the same format); ``ssh-keygen`` reads the private key, asks for
its passphrase or talks to the agent, so no private key ever enters orthospec; and every
signature can be checked without orthospec, by anyone with OpenSSH::

    printf %s "$STATEMENT" | ssh-keygen -Y verify -f allowed_signers -I "M. Rossi" \\
        -n orthospec-ledger -s entry.sig

The allowed-signers file (``ssh-keygen(1)`` ALLOWED SIGNERS; ``$ORTHOSPEC_ALLOWED_SIGNERS`` or
``--allowed-signers``) is the buyer's register of who is who: principal (a name or an e-mail)
and key, optionally ``valid-after``/``valid-before``. It lives outside the ledger: a key the
ledger's editor adds to the ledger names nobody. A signature is checked at the date it was
recorded (``-Overify-time``), so a key retired later still verifies what it signed while valid.

What is signed (:func:`statement`) is the canonical JSON of what the entry vouches for: for a run
the SHA-256 of its qcr.json (the whole result: delivery, verdict, records, operator); for a
sign-off the signed run's chain hash, the date, role, note and manual verdicts (the name is the
key's principal in the allowed-signers file, checked when the signature is verified).
"""

from __future__ import annotations

import base64
import hashlib
import os
import shutil
import struct
import subprocess
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import LedgerError
from .chain import canonical

#: the SSHSIG namespace of every ledger signature (a signature made for git or a file is not one)
NAMESPACE = "orthospec-ledger"
ENV_KEY = "ORTHOSPEC_SIGNING_KEY"
ENV_ALLOWED = "ORTHOSPEC_ALLOWED_SIGNERS"
#: seconds ssh-keygen may take (a passphrase prompt or a hardware token touch included)
_TIMEOUT = 300

__all__ = [
    "ENV_ALLOWED",
    "ENV_KEY",
    "NAMESPACE",
    "Signature",
    "allowed_signers_from_env",
    "check_signature",
    "key_from_env",
    "sign",
    "signature_key",
    "statement",
    "verify_signature",
]


@dataclass(frozen=True)
class Signature:
    """One signature as stored with its ledger entry."""

    armored: str  # -----BEGIN SSH SIGNATURE----- ...
    fingerprint: str  # SHA256:... of the signing key (ssh-keygen -l style)
    principal: str | None  # who the allowed-signers file says the key is; None without one


def statement(kind: str, fields: Mapping[str, Any]) -> bytes:
    """The bytes a ledger entry's signature covers: canonical JSON, ``kind`` first-class."""
    return canonical({"orthospec_ledger": kind, **fields}).encode("utf-8")


def run_statement(document_sha256: str) -> bytes:
    return statement("run", {"document_sha256": document_sha256})


def signoff_statement(row: Mapping[str, Any]) -> bytes:
    """What a sign-off's signature covers: the run signed (its chain hash), date, role, note and manual
    verdicts. Not the name: the signer is the key, named by the allowed-signers file."""
    return statement("signoff", {k: row[k] for k in ("run_hash", "date", "role", "note", "manual")})


def key_from_env() -> Path | None:
    v = os.environ.get(ENV_KEY)
    return Path(v) if v else None


def allowed_signers_from_env() -> Path | None:
    v = os.environ.get(ENV_ALLOWED)
    return Path(v) if v else None


def _ssh_keygen() -> str:
    exe = shutil.which("ssh-keygen")
    if exe is None:
        raise LedgerError(
            "ssh-keygen not found: ledger signatures need OpenSSH's ssh-keygen "
            "(Debian/Ubuntu: apt-get install openssh-client)"
        )
    return exe


def _run(args: list[str], *, data: bytes | None = None) -> subprocess.CompletedProcess[bytes]:
    try:
        return subprocess.run(
            [_ssh_keygen(), *args], input=data, capture_output=True, timeout=_TIMEOUT, check=False
        )
    except subprocess.TimeoutExpired:
        raise LedgerError(
            f"ssh-keygen {args[0]} {args[1]} did not finish in {_TIMEOUT} s"
        ) from None


def _read_string(buf: bytes, pos: int) -> tuple[bytes, int]:
    if pos + 4 > len(buf):
        raise ValueError("truncated")
    (n,) = struct.unpack(">I", buf[pos : pos + 4])
    if pos + 4 + n > len(buf):
        raise ValueError("truncated")
    return buf[pos + 4 : pos + 4 + n], pos + 4 + n


def signature_key(armored: str) -> tuple[str, str]:
    """(fingerprint ``SHA256:...``, key type) of the public key an SSH signature carries.

    Read from the SSHSIG blob (PROTOCOL.sshsig: "SSHSIG", version, public key, namespace, ...);
    the fingerprint is what ``ssh-keygen -l`` prints for that key. No cryptography here: whether
    the signature is valid is :func:`verify_signature`'s question."""
    body = "".join(line.strip() for line in armored.strip().splitlines()[1:-1])
    try:
        blob = base64.b64decode(body, validate=True)
        if blob[:6] != b"SSHSIG":
            raise ValueError("no SSHSIG preamble")
        key, _ = _read_string(blob, 10)
        key_type, _ = _read_string(key, 0)
    except (ValueError, struct.error) as exc:
        raise LedgerError(f"not an SSH signature ({exc})") from None
    digest = base64.b64encode(hashlib.sha256(key).digest()).decode("ascii").rstrip("=")
    return f"SHA256:{digest}", key_type.decode("ascii", "replace")


def _principals(sig_file: Path, allowed: Path) -> list[str]:
    res = _run(["-Y", "find-principals", "-s", str(sig_file), "-f", str(allowed)])
    if res.returncode != 0:
        return []
    return [ln.strip() for ln in res.stdout.decode("utf-8", "replace").splitlines() if ln.strip()]


def sign(message: bytes, key: Path, *, allowed_signers: Path | None) -> Signature:
    """Sign ``message`` with the private key at ``key`` (or the agent's, given its ``.pub``).

    With an allowed-signers file the key must be listed there (else the signature would name
    nobody): its principal is returned. Raises :class:`LedgerError` with ssh-keygen's reason."""
    if not Path(key).is_file():
        raise LedgerError(
            f"signing key {key}: no such file (give --key or ${ENV_KEY}: an SSH private key, "
            "or the .pub of a key held by ssh-agent)"
        )
    res = _run(["-Y", "sign", "-q", "-f", str(key), "-n", NAMESPACE], data=message)
    if res.returncode != 0 or b"BEGIN SSH SIGNATURE" not in res.stdout:
        why = res.stderr.decode("utf-8", "replace").strip() or f"exit {res.returncode}"
        raise LedgerError(f"signing with {key} failed: {why}")
    armored = res.stdout.decode("ascii")
    fingerprint, _ = signature_key(armored)
    principal = None
    if allowed_signers is not None:
        _check_allowed(allowed_signers)
        with tempfile.TemporaryDirectory(prefix="orthospec-sig-") as tmp:
            sig = Path(tmp) / "entry.sig"
            sig.write_text(armored, encoding="ascii")
            found = _principals(sig, allowed_signers)
        if not found:
            raise LedgerError(
                f"the key {key} ({fingerprint}) is not in the allowed-signers file {allowed_signers}: "
                "a signature must name a person the buyer registered"
            )
        principal = found[0]
    return Signature(armored, fingerprint, principal)


def _check_allowed(path: Path) -> None:
    if not Path(path).is_file():
        raise LedgerError(
            f"allowed-signers file {path}: no such file (${ENV_ALLOWED} or --allowed-signers)"
        )


def check_signature(message: bytes, armored: str) -> str | None:
    """None when ``armored`` is a valid ledger signature of ``message`` by the key it carries; else why not.

    In-process through the ``sshsig`` package (Ed25519 and RSA keys: microseconds, so `verify` of a
    long ledger stays fast); other key types (ECDSA, FIDO) through ``ssh-keygen -Y check-novalidate``.
    Who the key is, is :func:`verify_signature`'s question."""
    import sshsig

    try:
        sshsig.check_signature(message, armored, namespace=NAMESPACE)
        return None
    except sshsig.InvalidSignature as exc:
        return f"invalid signature{f' ({exc})' if str(exc) else ''}"
    except (NotImplementedError, ValueError):
        return verify_signature(message, armored, principal=None, allowed_signers=None)


def verify_signature(
    message: bytes,
    armored: str,
    *,
    principal: str | None,
    allowed_signers: Path | None,
    day: str | None = None,
) -> str | None:
    """None when ``armored`` is a valid ledger signature of ``message``; else why not.

    With an allowed-signers file: by ``principal``'s key as registered there, at ``day`` (YYYY-MM-DD,
    the entry's recording date). Without one: only that the signature is valid for the key it
    carries (who that key is stays unknown)."""
    with tempfile.TemporaryDirectory(prefix="orthospec-sig-") as tmp:
        sig = Path(tmp) / "entry.sig"
        sig.write_text(armored, encoding="ascii")
        if allowed_signers is None:
            res = _run(["-Y", "check-novalidate", "-n", NAMESPACE, "-s", str(sig)], data=message)
        else:
            _check_allowed(allowed_signers)
            who = principal
            if who is None:
                found = _principals(sig, allowed_signers)
                if not found:
                    return (
                        f"signed by a key that is not in the allowed-signers file {allowed_signers}"
                    )
                who = found[0]
            args = [
                "-Y",
                "verify",
                "-f",
                str(allowed_signers),
                "-I",
                who,
                "-n",
                NAMESPACE,
                "-s",
                str(sig),
            ]
            if day:
                args.append(f"-Overify-time={day.replace('-', '')[:8]}")
            res = _run(args, data=message)
    if res.returncode == 0:
        return None
    why = (res.stderr or res.stdout).decode("utf-8", "replace").strip().splitlines()
    return why[-1] if why else f"ssh-keygen exit {res.returncode}"
