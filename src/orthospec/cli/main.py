"""Entry point: run the lazy click group (``groups.py``) and map errors to exit codes.

Exit codes: 0 accepted / success, 1 rejected, 2 could not evaluate (bad input or arguments).
"""

from __future__ import annotations

import os
import sys

import click

from ..errors import OrthospecError
from . import groups

_loaded = False


def _load_commands() -> None:
    """Import every ``cmd_*`` module (tests walk the complete tree; the CLI itself never needs to)."""
    global _loaded
    if _loaded:
        return
    import importlib
    import pkgutil

    package = sys.modules[__package__]
    for info in sorted(pkgutil.iter_modules(package.__path__), key=lambda i: i.name):
        if info.name.startswith("cmd_"):
            importlib.import_module(f"{__package__}.{info.name}")
    _loaded = True


def cli() -> click.Group:
    """The fully registered click group (for CliRunner in tests)."""
    _load_commands()
    return groups.main


def main(argv: list[str] | None = None) -> None:
    """The ``orthospec`` executable: only the invoked command's module is imported."""
    # orthospec's parallelism is its own (threads, worker processes, Dask); OpenBLAS's threads,
    # started for the few small matrix products (band misregistration), only spin beside it:
    # 0.4-1.0 s of CPU in a 1,000,000-point check on 2 cores. Set before numpy loads; a value
    # the user set is kept.
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    debug = "--debug" in (argv if argv is not None else sys.argv[1:])
    if debug:
        # the engine keeps the traceback of a crashing rule in its records (engine/rules.py safe());
        # an environment switch, so that `--help` still imports no engine
        os.environ["ORTHOSPEC_DEBUG"] = "1"
    try:
        rv = groups.main.main(args=argv, prog_name="orthospec", standalone_mode=False)
    except OrthospecError as exc:
        click.echo(f"error: {exc}", err=True)
        sys.exit(exc.exit_code)
    except click.exceptions.Abort:
        click.echo("aborted", err=True)
        sys.exit(2)
    except click.ClickException as exc:
        exc.show()
        sys.exit(2)
    except click.exceptions.Exit as exc:
        sys.exit(exc.exit_code)
    except KeyboardInterrupt:
        click.echo("interrupted", err=True)
        sys.exit(2)
    except (
        Exception
    ) as exc:  # documented broad catch, never swallowing: an internal bug is reported
        # plainly (exit 2) instead of a traceback, and re-raised with its traceback under --debug
        if debug:
            raise
        click.echo(
            f"internal error: {type(exc).__name__}: {exc} (run with --debug for details)", err=True
        )
        sys.exit(2)
    # the work is done and written: skip the interpreter's final collection of the whole heap
    # (numpy, rasterio, ... loaded), tens of ms at every exit (issue 14); teardown still runs
    import gc

    gc.freeze()
    sys.exit(rv if isinstance(rv, int) else 0)


if __name__ == "__main__":
    main()
