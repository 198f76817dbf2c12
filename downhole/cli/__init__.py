"""The ``downhole`` command line: one typer app; each module of this package adds its commands.

Modules register commands on :data:`app` at import (``@app.command()``) or add sub-apps
(``app.add_typer(...)``). :func:`main` turns input errors into one-line messages and exit code 2,
and a stop signal into one line and exit code 128 + the signal: SIGTERM and SIGHUP (a closed
terminal, a dropped SSH session) stop a command like SIGINT (Ctrl-C) does, so that its output
folder keeps the ``INCOMPLETE`` marker with the reason and its worker processes are killed
(see docs/architecture.md, "Signals, locks and full disks").
"""

from __future__ import annotations

import importlib
import pkgutil
import sys

import typer

__all__ = ["app", "fail", "main"]

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                  rich_markup_mode=None,
                  help="downhole: drilling dynamics, optimization and control.")


#: SIGINT seen by :func:`main`'s handler; whether a command reported its end itself (``fail``).
_sigint = {"seen": False, "reported": False}


def fail(message: str, code: int = 2):
    """Print ``error: message`` to stderr and exit with ``code`` (no traceback)."""
    typer.echo(f"error: {message}", err=True)
    _sigint["reported"] = True
    raise typer.Exit(code)


def _on_sigint(signum, frame):
    """SIGINT in :func:`main`: ``KeyboardInterrupt`` as usual, remembered (typer turns it into a
    silent exit code 130, which :func:`main` completes with its one line)."""
    _sigint["seen"] = True
    raise KeyboardInterrupt


def _load_commands() -> None:
    for mod in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        if not mod.name.startswith("_"):
            importlib.import_module(f"{__name__}.{mod.name}")


def _click_exception_types() -> tuple:
    types = []
    for mod in ("click.exceptions", "typer._click.exceptions"):
        try:
            types.append(importlib.import_module(mod).ClickException)
        except (ImportError, AttributeError):
            pass
    return tuple(types)


def _os_error_line(exc: OSError) -> str:
    """One line for an operating-system error (``[Errno 28] No space left on device: 'x'``);
    HDF5's multi-line messages are cut to their first line."""
    import errno as _errno

    what = exc.strerror or str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    name = exc.filename or ""
    hint = {_errno.ENOSPC: "free some space or choose another --out",
            _errno.EDQUOT: "the disk quota is exceeded: free some space or choose another --out",
            _errno.EROFS: "the file system is read-only: choose another --out"}.get(exc.errno)
    line = f"{what}" + (f": {name}" if name else "") + (f" ({hint})" if hint else "")
    return " ".join(line.split())


#: Appended to the line of a command stopped by a signal.
STOPPED = "the run did not finish (outputs it had not written are marked INCOMPLETE)"


def _interrupted(exc: BaseException) -> bool:
    """Whether ``exc`` is SIGINT's ``KeyboardInterrupt`` (click turns it into ``Abort``)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def main(argv: list[str] | None = None) -> int:
    """Console-script entry point.

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit code: 0, 1 (a run that failed, the environment: a full disk), 2 (bad input),
        128 + N (stopped by signal N: 130 for SIGINT, 143 for SIGTERM, 129 for SIGHUP).
    """
    import signal
    import threading

    from downhole._workers import StopRequested, stop_on_signals
    from downhole.errors import DownholeError, DownholeInputError

    def _code(code: int) -> int:
        if code == 128 + signal.SIGINT and _sigint["seen"] and not _sigint["reported"]:
            typer.echo(f"error: interrupted (SIGINT); {STOPPED}", err=True)
        return code

    _load_commands()
    _sigint.update(seen=False, reported=False)
    previous = None
    if threading.current_thread() is threading.main_thread() \
            and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        previous = signal.signal(signal.SIGINT, _on_sigint)  # not if ignored (a background job)
    try:
        with stop_on_signals():
            rc = app(args=argv, standalone_mode=False)
        # with standalone_mode=False click returns the code of a typer.Exit instead of raising
        if isinstance(rc, int):
            return _code(rc)
    except typer.Exit as exc:
        return _code(exc.exit_code)
    except StopRequested as exc:  # SIGTERM, SIGHUP
        typer.echo(f"error: {exc}; {STOPPED}", err=True)
        return 128 + exc.signum
    except KeyboardInterrupt:
        typer.echo(f"error: interrupted (SIGINT); {STOPPED}", err=True)
        return 128 + signal.SIGINT
    except SystemExit as exc:  # click usage errors
        return int(exc.code or 0)
    except DownholeInputError as exc:
        typer.echo(f"error: {exc}", err=True)
        return 2
    except DownholeError as exc:  # a run that failed (e.g. went non-finite): exit code 1
        typer.echo(f"error: {exc}", err=True)
        return 1
    except OSError as exc:  # the environment: a full disk, a quota, a read-only folder
        typer.echo(f"error: {_os_error_line(exc)}", err=True)
        return 1
    except KeyError as exc:  # unknown preset / experiment ids carry their message
        typer.echo(f"error: {exc.args[0] if exc.args else exc}", err=True)
        return 2
    except Exception as exc:  # click's own usage errors (typer may vendor click)
        if _interrupted(exc):  # SIGINT: click raised Abort from the KeyboardInterrupt
            typer.echo(f"error: interrupted (SIGINT); {STOPPED}", err=True)
            return 128 + signal.SIGINT
        click_exc = _click_exception_types()
        if isinstance(exc, click_exc):
            exc.show()
            return exc.exit_code
        raise
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
