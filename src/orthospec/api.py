"""The library entry points the CLI (and other programs) call."""

from __future__ import annotations

import collections
import contextlib
import datetime as dt
import errno
import gc
import mmap
import os
import re
import shutil
import tempfile
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from . import verdicts as V
from .delivery.reader import Delivery, open_delivery
from .engine import catalog
from .engine.evaluator import Evaluation, Evaluator
from .engine.params import parse_cli_params, resolve_parameters
from .engine.registry import EngineOptions
from .errors import OrthospecError
from .profile.loader import ResolvedProfile, load_profile
from .qcr import Output, build_document, render_all

#: every output format orthospec itself writes (plugins add more: the orthospec.formats entry point)
FORMATS = ("terminal", "json", "csv", "junit", "parquet", "html", "pdf", "gpkg", "iso19157")
#: the formats drawing a map: their footprints go into qcr.json (``details.footprints``)
MAP_FORMATS = frozenset({"gpkg", "html", "pdf"})


@dataclass
class CheckResult:
    document: dict[str, Any]
    evaluation: Evaluation
    _geometry: Any = field(default=None, repr=False, compare=False)

    @property
    def accepted(self) -> bool:
        return self.document["verdict"] == V.ACCEPTED

    def with_maps(self, formats: Iterable[str]) -> dict[str, Any]:
        """The document as written with ``formats``: when one draws a map (gpkg, html, pdf) the
        image footprints read from the raster headers go into it (``details.footprints``), so the
        map re-renders from qcr.json alone. Done once; :attr:`document` is the result."""
        if MAP_FORMATS & set(formats) and self._geometry is None:
            from .findings import read_geometry, with_footprints

            self._geometry = read_geometry(self.evaluation.delivery)
            self.document = with_footprints(self.document, self._geometry)
        return self.document

    def outputs(
        self, formats: Iterable[str], *, shown: dict[str, Any] | None = None
    ) -> dict[str, Output]:
        """Every requested file (terminal left out), rendered but not written: machine outputs of
        :attr:`document`, HTML/PDF reports of ``shown`` (the document with the ledger's history for
        the reader; qcr.json never carries it), the GeoPackage of the findings, ISO 19139 XML and the
        updated copies of the delivery's metadata."""
        fmts = [f for f in formats if f != "terminal"]
        doc = self.with_maps(fmts)
        out = render_all(doc, [f for f in fmts if f not in ("gpkg", "iso19157")])
        if "gpkg" in fmts:
            from .findings import to_gpkg

            out["findings.gpkg"] = to_gpkg(doc, self._geometry)
        if (
            "iso19157" in fmts
        ):  # the ISO 19157 document and updated copies of the delivery's metadata
            from .metadata.copies import metadata_outputs

            out.update(metadata_outputs(doc, self.evaluation.delivery))
        if "html" in fmts or "pdf" in fmts:
            from .reports import document as reportdoc  # heavy imports only when asked for

            out.update(
                reportdoc.render(
                    shown if shown is not None else doc,
                    formats=[f for f in fmts if f in ("html", "pdf")],
                )
            )
        return out

    def render(self, formats: Iterable[str], out: str | Path) -> list[str]:
        """Write the requested files into the folder ``out``, all or none (never into the
        delivery); returns the names written."""
        refuse_inside_delivery(out, self.evaluation.delivery.root, what="output folder")
        return write_outputs(out, self.outputs(formats))


@dataclass(frozen=True)
class CheckOptions:
    """How a check runs (typed: issue 15 item 4). Of these only ``checker`` (the checker's manual
    verdicts and waivers in force), ``sample`` (which items are checked) and ``fail_on`` (whether
    warnings block) can change a verdict."""

    #: worker processes for raster checks (None: the engine decides, at most the cores)
    workers: int | None = None
    #: Dask distributed scheduler address (``check --scheduler``)
    scheduler: str | None = None
    #: show a progress line on stderr while rasters are scanned
    progress: bool = False
    #: only those items are checked: the sample table's path (from ``orthospec sample``), or
    #: ``(scope, items)`` as :func:`orthospec.engine.sample.read_sample` gives; qcr.json's ``sample``
    #: block says what the check was restricted to
    sample: tuple[str, frozenset[str] | set[str]] | str | Path | None = None
    #: the checker's file (YAML, outside the delivery): manual-check verdicts and waivers in force
    checker: Path | None = None
    #: "fail", or "warn" to make recommended-level rules blocking
    fail_on: str = V.FAIL
    #: raster result cache folder (results keyed by file SHA-256)
    cache_dir: Path | None = None
    #: offending items the terminal summary lists per rule (qcr.json lists all)
    max_items: int = 8

    def __post_init__(self) -> None:
        if self.fail_on not in (V.FAIL, V.WARN):
            raise OrthospecError(f"fail_on must be 'fail' or 'warn', got {self.fail_on!r}")
        if self.workers is not None and (
            isinstance(self.workers, bool) or not isinstance(self.workers, int) or self.workers < 1
        ):
            raise OrthospecError(f"workers must be a whole number >= 1, got {self.workers!r}")
        if (
            isinstance(self.max_items, bool)
            or not isinstance(self.max_items, int)
            or self.max_items < 1
        ):
            raise OrthospecError(f"max_items must be a whole number >= 1, got {self.max_items!r}")

    @classmethod
    def of(cls, options: CheckOptions | Mapping[str, Any] | None) -> CheckOptions:
        """Options as given: a CheckOptions, or a mapping of its field names (unknown names refused)."""
        if options is None:
            return cls()
        if isinstance(options, CheckOptions):
            return options
        known = {f.name for f in fields(cls)}
        bad = sorted(set(options) - known)
        if bad:
            raise OrthospecError(
                f"unknown check option(s) {', '.join(bad)}; known: {', '.join(sorted(known))}"
            )
        given = {k: v for k, v in options.items() if v is not None}
        for k in ("checker", "cache_dir"):
            if k in given:
                given[k] = Path(given[k])
        return cls(**given)

    def engine_options(self) -> EngineOptions:
        """What the evaluator and its providers read (typed and frozen: engine/registry.py)."""
        assert self.sample is None or isinstance(self.sample, tuple), (
            "check() reads a sample table's path first"
        )
        return EngineOptions(
            workers=self.workers,
            scheduler=self.scheduler,
            progress=self.progress,
            sample=self.sample,
            cache_dir=None if self.cache_dir is None else str(self.cache_dir),
        )


def parse_date(text: str | None) -> str:
    if text is None:
        return dt.date.today().isoformat()
    try:
        return dt.date.fromisoformat(text).isoformat()
    except ValueError:
        raise OrthospecError(f"--date {text!r}: expected YYYY-MM-DD") from None


def check(
    delivery: str | Path | Delivery,
    profile: str | Path | ResolvedProfile,
    *,
    params: Mapping[str, str] | list[str] | tuple[str, ...] = (),
    date: str | None = None,
    fail_on: str | None = None,
    operator: str | None = None,
    checker: str | Path | None = None,
    options: CheckOptions | Mapping[str, Any] | None = None,
    ledger: str | Path | None = None,
    allowed_signers: str | Path | None = None,
) -> CheckResult:
    """Check a delivery against a profile; bad input raises OrthospecError, failures are QCRs.

    ``fail_on`` and ``checker`` given here win over the same fields of ``options``. ``ledger``
    (SQLite path or PostgreSQL URL) is opened and verified before the check and its chain head goes
    into the document (``ledger_head``: the head the run extends when it is recorded there)."""
    opts = CheckOptions.of(options)
    ledger_head = None
    if ledger is not None:
        from .ledger import head_for_check

        if "://" not in str(ledger):  # a ledger file is never written inside the delivery
            root = delivery.root if isinstance(delivery, Delivery) else delivery
            refuse_inside_delivery(ledger, root, what="--ledger")
        ledger_head = head_for_check(str(ledger), allowed_signers=allowed_signers)
    sample_file = None
    if isinstance(opts.sample, str | Path):
        from .engine.sample import read_sample

        sample_file = Path(opts.sample)
        opts = replace(opts, sample=read_sample(sample_file))
    if fail_on is not None:
        opts = replace(opts, fail_on=fail_on)
    if checker is not None:
        opts = replace(opts, checker=Path(checker))
    if opts.scheduler is not None:
        from .raster.parallel import require_dask

        require_dask()  # a missing extra is exit 2 before any work, not an error record per image
    prof = profile if isinstance(profile, ResolvedProfile) else load_profile(profile)
    d = delivery if isinstance(delivery, Delivery) else open_delivery(delivery)
    chk = None
    if opts.checker is not None:
        from .delivery.checker import load_checker

        chk = load_checker(opts.checker, delivery_root=d.root, delivery=d)  # bound to this delivery
    with _fewer_collections():
        preloading = catalog.preload()
        try:
            d.load_all_tables()
        finally:
            preloading.join()  # never left importing while the interpreter exits on a bad table
        cli = dict(params) if isinstance(params, Mapping) else parse_cli_params(list(params))
        values = resolve_parameters(
            prof,
            dict(d.manifest.tender.parameters) if d.manifest.tender else {},
            cli,
            manifest=d.flat_manifest(),
            checker=chk,
        )
        ev = Evaluator(
            prof, d, values, fail_on=opts.fail_on, options=opts.engine_options(), checker=chk
        ).run()
        # the delivery folder's own name: the same bytes whatever the working folder or the path typed
        doc = build_document(
            ev, date=parse_date(date), operator=operator, delivery_path=d.root.name
        )
    statements = _nssda(doc)
    if statements:
        doc["nssda"] = statements
    if ledger_head is not None:
        doc["ledger_head"] = ledger_head  # the chain head this run extends (issue 13 item 5)
    if opts.sample is not None:
        assert isinstance(opts.sample, tuple)
        doc["sample"] = _sample_block(opts.sample, d, sample_file)
    return CheckResult(doc, ev)


def diff(a: str | Path | ResolvedProfile, b: str | Path | ResolvedProfile, *, prose: bool = False
         ) -> dict[str, Any]:
    """What changed from profile ``a`` to ``b`` (``orthospec spec diff``, text or ``--json``):
    rules and parameters added, removed, changed (prose fields only with ``prose``), the mandatory
    rules a tender weakened, and ``through_parameters``: the rules whose effective requirement
    changed only because a parameter did, worded as the QCR and the annex word it."""
    from .profile.diff import diff_profiles
    from .reports.annex import requirement_text

    pa = a if isinstance(a, ResolvedProfile) else load_profile(a)
    pb = b if isinstance(b, ResolvedProfile) else load_profile(b)
    d = diff_profiles(pa, pb)
    if not prose:
        for kind in ("parameters", "rules"):
            d[kind]["changed"] = {
                name: kept for name, fields_ in d[kind]["changed"].items()
                if (kept := {f: v for f, v in fields_.items()
                             if f.split(".")[-1] not in ("description", "note", "title")})}
    if (pa.id, pa.version) == (pb.id, pb.version) and pa.sha256 != pb.sha256:
        d["warning"] = (f"warning: both files say {pa.id} {pa.version} but their contents differ (sha256 "
                        f"{pa.sha256[:12]}… vs {pb.sha256[:12]}…): give the changed profile a new version")
    through: list[dict[str, str]] = []
    if d["parameters"]["changed"] or d["parameters"]["added"]:
        for r in pb.rules:
            if r.id in d["rules"]["changed"] or r.id in d["rules"]["added"]:
                continue
            try:
                old_rule = pa.rule(r.id)
            except KeyError:
                continue
            ra = requirement_text(old_rule.requirement, dict(pa.parameters))
            rb = requirement_text(r.requirement, dict(pb.parameters))
            if ra != rb:
                through.append({"id": r.id, "before": ra, "after": rb})
    d["through_parameters"] = through
    return d


def _nssda(doc: dict[str, Any]) -> list[dict[str, Any]]:
    """FGDC-STD-007.3 §3.2.3 reporting statements ("Tested 0.683 meters horizontal accuracy at 95%
    confidence level"), one per block and axis, when the profile judges an NSSDA figure; [] otherwise
    (the records are only walked when a rule measures one)."""
    from .metadata.nssda import H_MEASURE, V_MEASURE, nssda_statements

    if not any(r.get("measure") in (H_MEASURE, V_MEASURE) for r in doc.get("rules") or ()):
        return []
    return [s.as_dict() for s in nssda_statements(doc)]


def _sample_block(
    sample: tuple[str, frozenset[str] | set[str]], d: Delivery, sample_file: Path | None
) -> dict[str, Any]:
    """What the sample restricted the check to, for the QCR (JRC §12.3 / §12.8)."""
    scope, items = sample
    images = d.table("images") if scope != "block" and d.has_table("images") else None
    total = len(d.block_ids) if scope == "block" else (len(images.df) if images is not None else 0)
    clause = "§12.8" if scope == "block" else "§12.3"
    source = f"file {sample_file.name}, " if sample_file is not None else ""
    return {
        "kind": scope,
        "items": sorted(items),
        "statement": f"sample of {len(items)} of {total} {scope}s ({source}JRC {clause})",
    }


@contextlib.contextmanager
def _fewer_collections(first: int = 100_000) -> Iterator[None]:
    """The cyclic garbage collector's first threshold raised to ``first`` during a check.

    A national check allocates millions of small containers (ids, evidence, records) that die
    young or live to the end; at the default 700 the collector ran 438 times over them at
    1,000,000 check points (0.30 s), at 100,000 twice (0.09 s). Restored afterwards."""
    old = gc.get_threshold()
    gc.set_threshold(max(first, old[0]), *old[1:])
    try:
        yield
    finally:
        gc.set_threshold(*old)


# --------------------------------------------------------------------------- outputs
# orthospec never writes into a delivery and never outside the output folder (issue 17).

_UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")


def safe_segment(text: str, *, default: str = "delivery") -> str:
    """``text`` as one harmless path segment: ``../../x`` -> ``x``, ``/a/b`` -> ``a_b``.

    A delivery id is contractor text; used as a folder name it must not climb out of the
    output folder, be absolute, or be hidden.
    """
    seg = _UNSAFE.sub("_", str(text)).strip("._-")[:100].rstrip("._-")
    return seg or default


def inside(path: str | Path, root: str | Path) -> bool:
    """True when ``path`` (existing or not, symlinks resolved) is ``root`` or lies under it."""
    return Path(path).resolve().is_relative_to(Path(root).resolve())


def refuse_inside_delivery(path: str | Path, delivery: str | Path, *, what: str) -> None:
    """Raise OrthospecError (exit 2) when an output path would land inside the delivery."""
    if Path(delivery).is_dir() and inside(path, delivery):
        raise OrthospecError(
            f"{what} {str(path)!r} is inside the delivery {str(delivery)!r}; orthospec "
            "never writes into a delivery: choose a folder outside it"
        )


def default_output_dir(delivery_id: str, *, base: str | Path = "reports") -> Path:
    """``reports/<id>`` with the id reduced to one safe path segment."""
    return Path(base) / safe_segment(delivery_id)


class _Synced:
    """One output file, written in order and fsynced on close; large files bypass the page cache.

    Every output is fsynced, so copying its bytes into the page cache first is pure cost, and a
    high one where fresh memory is expensive (a VM that hands pages back to its host): 430 MB took
    1.15-1.34 s buffered + fsync and 0.17-0.23 s with O_DIRECT on the 2-core VM (issue 14). Files
    of ``SPAN`` bytes or more go out in whole 4 KiB blocks from an aligned buffer with O_DIRECT;
    the tail, smaller files and every file on a file system that refuses O_DIRECT (tmpfs) are
    written normally. The same bytes either way.
    """

    BLOCK = 4096
    #: bytes gathered before a direct write; files smaller than this never use O_DIRECT
    SPAN = 1 << 20

    def __init__(self, path: Path) -> None:
        self.fd = os.open(
            path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0), 0o600
        )
        self.buf: mmap.mmap | None = None  # page-aligned, as O_DIRECT requires
        self.held = 0  # bytes waiting in buf
        self.direct = bool(_O_DIRECT)  # until the file system refuses it
        self.flushed = False  # blocks written from the buffer (a large file)

    def write(self, data: bytes) -> None:
        view = memoryview(data)
        if not self.direct and not self.held:
            self._write_all(view)  # (bytes still held go first, through the buffer)
            return
        if self.buf is None:
            self.buf = mmap.mmap(-1, 2 * self.SPAN)
        while len(view):
            take = min(len(view), 2 * self.SPAN - self.held)
            self.buf[self.held : self.held + take] = view[:take]
            self.held += take
            view = view[take:]
            if self.held >= self.SPAN:
                self._flush_blocks()

    def _flush_blocks(self) -> None:
        """Write the whole blocks held (directly, when the file system lets us); keep the rest."""
        assert self.buf is not None
        n = self.held - self.held % self.BLOCK
        if self.direct and not self._set_direct(True):
            self.direct = False
        with memoryview(self.buf) as mv:
            self._write_all(mv[:n])
        self.flushed = True
        self.held -= n
        if self.held:
            self.buf.move(0, n, self.held)

    def _set_direct(self, on: bool) -> bool:
        import fcntl  # POSIX only; reached only where os.O_DIRECT exists

        flags = fcntl.fcntl(self.fd, fcntl.F_GETFL)
        want = flags | _O_DIRECT if on else flags & ~_O_DIRECT
        if want != flags:
            try:
                fcntl.fcntl(self.fd, fcntl.F_SETFL, want)
            except OSError:  # EINVAL: no direct I/O on this file system
                return False
        return True

    def _write_all(self, view: memoryview) -> None:
        while len(view):
            try:
                done = os.write(self.fd, view)
            except OSError as exc:
                if exc.errno != errno.EINVAL or not self.direct:
                    raise
                self.direct = False  # direct I/O refused at write time: the same bytes, buffered
                self._set_direct(False)
                continue
            view = view[done:]

    def close_synced(self) -> None:
        try:
            if self.held:
                assert self.buf is not None
                if self.flushed:
                    self._flush_blocks()  # a large file's last whole blocks, as the others
                if self.direct:
                    self._set_direct(
                        False
                    )  # the tail is not a whole block; a small file, no buffer games
                with memoryview(self.buf) as mv:
                    self._write_all(mv[: self.held])
                self.held = 0
            os.fsync(self.fd)
        finally:
            self.close()

    def close(self) -> None:
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1
        if self.buf is not None:
            with contextlib.suppress(BufferError):  # a view held by a write error's traceback:
                self.buf.close()  # the mapping goes with the last view
            self.buf = None


_O_DIRECT = getattr(os, "O_DIRECT", 0)


class _Stager:
    """Writes the outputs' bytes in one background thread while the caller renders the next piece.

    Rendering a national qcr.csv or junit.xml holds the GIL; the writes and ``fsync`` do not, so
    they overlap (the 450 MB a 1,000,000-point check writes, issue 14). One thread keeps every file's
    pieces in order; at most ``QUEUE`` pieces of about ``PIECE`` bytes wait (bounded memory). An
    error in the thread is raised in the caller with the name of the output it was writing.
    """

    PIECE = 1 << 20
    QUEUE = 2

    def __init__(self, tmp: Path) -> None:
        from concurrent.futures import ThreadPoolExecutor

        self.tmp = tmp
        self.pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="orthospec-write")
        self.pending: collections.deque[tuple[str, Any]] = collections.deque()
        self.handles: list[_Synced] = []
        self.failed = ""  # the output whose write failed

    def __enter__(self) -> _Stager:
        return self

    def __exit__(self, *exc: object) -> None:
        self.pool.shutdown(wait=True, cancel_futures=True)
        for fh in self.handles:  # after an error, the files the thread did not close
            fh.close()

    def _submit(self, name: str, fn: Any, *args: Any) -> None:
        self.pending.append((name, self.pool.submit(fn, *args)))
        while len(self.pending) > self.QUEUE:
            self._wait_one()

    def _wait_one(self) -> str:
        name, fut = self.pending.popleft()
        try:
            fut.result()
        except OSError:
            self.failed = name
            raise
        return name

    def file(self, i: int, name: str, data: str | bytes | Iterable[str]) -> None:
        """Stage output ``name`` as ``new-<i>``: opened, written piece by piece, fsynced, closed."""
        fh = _Synced(self.tmp / f"new-{i}")
        self.handles.append(fh)
        if isinstance(data, str | bytes):
            self._submit(name, fh.write, data.encode("utf-8") if isinstance(data, str) else data)
        else:
            buf: list[bytes] = []
            size = 0
            for piece in data:
                b = piece.encode("utf-8")
                buf.append(b)
                size += len(b)
                if size >= self.PIECE:
                    self._submit(name, fh.write, b"".join(buf))
                    buf, size = [], 0
            if buf:
                self._submit(name, fh.write, b"".join(buf))
        self._submit(name, fh.close_synced)

    def finish(self) -> None:
        """Wait for every write."""
        while self.pending:
            self._wait_one()


def write_outputs(
    target: str | Path, files: Mapping[str, str | bytes | Iterable[str]]
) -> list[str]:
    """Write every output or none: render into a temporary folder inside ``target``, then move.

    A destination that exists and is not a regular file (a folder named ``junit.xml``, a
    symlink) refuses the whole set before anything is written; if a move still fails, the files
    already moved are put back as they were. An output may be a stream of text pieces (qcr.json:
    ``qcr.iter_dumps``), written as it is produced. Returns the names written.

    Raises
    ------
    OrthospecError
        naming the output that could not be written; nothing new is left in ``target``.
    """
    out = Path(target)
    for name in files:
        dest = out / name
        if dest.is_symlink() or (dest.exists() and not dest.is_file()):
            raise OrthospecError(
                f"cannot write {name} to {out}/: {dest} exists and is not a regular "
                "file; no output written"
            )
    created = [p for p in (out, *out.parents) if not p.exists()]
    try:
        out.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=".orthospec-out-", dir=out))
    except OSError as exc:
        raise OrthospecError(f"cannot create output folder {out}: {exc.strerror or exc}") from None
    moved: list[tuple[Path, Path | None]] = []
    current = ""
    stage = _Stager(tmp)
    try:
        mask = os.umask(0)
        os.umask(mask)
        with stage, _fewer_collections():  # the streams render millions of lines
            for i, (name, data) in enumerate(files.items()):
                current = name
                stage.file(i, name, data)
            stage.finish()
        for i in range(len(files)):
            os.chmod(tmp / f"new-{i}", 0o666 & ~mask)
        for i, name in enumerate(files):
            current = name
            dest = out / name
            backup = None
            if dest.exists():
                backup = tmp / f"old-{i}"
                os.link(dest, backup)
            os.replace(tmp / f"new-{i}", dest)
            moved.append((dest, backup))
    except (
        BaseException
    ) as exc:  # never swallowed: undone, then re-raised (an OSError as OrthospecError)
        for dest, backup in reversed(moved):
            if backup is not None:
                os.replace(backup, dest)
            else:
                dest.unlink(missing_ok=True)
        shutil.rmtree(tmp, ignore_errors=True)
        for p in created:
            try:
                p.rmdir()
            except OSError:
                break
        if isinstance(exc, OSError):
            current = stage.failed or current  # a write in the stager's thread names its own output
            raise OrthospecError(
                f"cannot write {current} to {out}/: {exc.strerror or exc}; no output written"
            ) from None
        raise  # a stream that fails while it is written (e.g. a plugin format): nothing is left behind
    shutil.rmtree(tmp, ignore_errors=True)
    return list(files)
