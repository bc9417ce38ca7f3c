"""The ``ivslam`` command group: thin entry points, one module per command.

Each command lives in ``ivslam_cli/commands/<name>.py`` and is imported only when it is
invoked (or when ``--help`` lists it), so ``ivslam --help`` never loads numba kernels.
Errors a user can cause become one line on stderr and a non-zero exit; ``--debug``
shows the traceback instead.

Exit codes: 0 success; 1 an I/O failure writing an output (disk full, device error) or an
internal error; 2 bad input (a file, an option, a configuration value, a limit exceeded);
3 data proven inconsistent under ``--strict``; 130 interrupted (SIGINT), 143 terminated
(SIGTERM). A signal ends the command through the same clean-up as an error: no temporary
file is left and no output is half written.
"""

from __future__ import annotations

import errno
import importlib
import os
import signal
import sys
import warnings
from typing import NoReturn

import click

from ivslam_cli import __version__, collector

COMMANDS = {
    "simulate": "ivslam_cli.commands.simulate",
    "inspect": "ivslam_cli.commands.inspect",
    "run": "ivslam_cli.commands.run",
    "report": "ivslam_cli.commands.report",
}


class UserError(click.ClickException):
    """A one-line error for the user, printed as ``ivslam: error: ...``."""

    def __init__(self, message: str, exit_code: int = 2):
        super().__init__(message)
        self.exit_code = exit_code

    def show(self, file=None) -> None:  # noqa: D401 - click API
        click.echo(f"ivslam: error: {self.format_message()}", err=True, file=file)


class IvslamGroup(click.Group):
    """Lazy command loading plus the error policy (one line unless ``--debug``)."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return list(COMMANDS)

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        module = COMMANDS.get(name)
        if module is None:
            return None
        return importlib.import_module(module).command

    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except (click.ClickException, click.exceptions.Exit, click.exceptions.Abort):
            raise
        except Exception as exc:
            if ctx.obj and ctx.obj.get("debug"):
                raise
            message, code = error_line(exc)
            raise UserError(message, code) from exc

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        """Run the command; every way it can end is one line on stderr and an exit code."""
        code = 0
        with _signals_as_exceptions():
            try:
                rv = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
                code = rv if isinstance(rv, int) else 0
            except click.exceptions.UsageError as exc:  # bad option or argument: one line, exit 2
                where = f" (see '{exc.ctx.command_path} --help')" if exc.ctx is not None else ""
                message = " ".join(exc.format_message().split())
                click.echo(f"ivslam: error: {message}{where}", err=True)
                code = exc.exit_code
            except click.ClickException as exc:
                exc.show()
                code = exc.exit_code
            except click.exceptions.Abort:
                click.echo("ivslam: interrupted", err=True)
                code = 130
            except Interrupted as exc:
                click.echo(f"ivslam: {exc}", err=True)
                code = 128 + exc.signum
        if standalone_mode:
            sys.exit(code)
        return code


def error_line(exc: Exception) -> tuple[str, int]:
    """The one-line message (without the ``ivslam: error:`` prefix) and exit code for ``exc``."""
    from ivslam_cli.errors import IvslamError

    if isinstance(exc, IvslamError):
        return str(exc), exc.exit_code
    if isinstance(exc, OSError):
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        code = 1 if exc.errno in IO_ERRNOS else 2
        if not where and code == 1:  # e.g. numba writing its kernel cache on a full disk
            where = "cannot write a cache or temporary file: "
        return f"{where}{exc.strerror or exc}", code
    if isinstance(exc, MemoryError):
        return "out of memory (an input larger than this machine can hold?)", 1
    # last resort: still one line, but say it is ours
    return f"internal error ({type(exc).__name__}: {exc}); rerun with --debug for a traceback", 1


#: errors of the device rather than of the path given: exit 1, not 2
IO_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.EFBIG, errno.ENOMEM}


class Interrupted(BaseException):
    """SIGINT or SIGTERM: unwinds like an error (every clean-up runs), then exits 128 + signal."""

    def __init__(self, signum: int):
        self.signum = signum
        name = {signal.SIGINT: "interrupted", signal.SIGTERM: "terminated (SIGTERM)"}.get(signum, f"signal {signum}")
        super().__init__(name)


class _signals_as_exceptions:
    """Raise :class:`Interrupted` on SIGINT/SIGTERM (main thread only; restored on exit)."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __enter__(self):
        import threading

        self.old = {}
        if threading.current_thread() is threading.main_thread():
            for sig in self.SIGNALS:
                self.old[sig] = signal.signal(sig, self._raise)
        return self

    @staticmethod
    def _raise(signum, frame):
        raise Interrupted(signum)

    def __exit__(self, *exc):
        for sig, old in self.old.items():
            signal.signal(sig, old)
        return False


@click.group(cls=IvslamGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, "--version", prog_name="ivslam")
@click.option("--debug", is_flag=True, help="Show full tracebacks on errors.")
@click.pass_context
def cli(ctx: click.Context, debug: bool) -> None:
    """Guaranteed (interval) SLAM over recorded robot logs.

    \b
    Typical session:
      ivslam simulate --scenario pairs -o sim.mcap
      ivslam inspect sim.mcap
      ivslam run sim.mcap --mode pairs -o result.h5
      ivslam report result.h5
    """
    ctx.ensure_object(dict)
    ctx.obj["debug"] = debug
    if not debug:  # numpy's RuntimeWarnings (NaN in, overflow) are not messages for the user
        warnings.simplefilter("ignore", RuntimeWarning)


def main(argv: list[str] | None = None) -> None:
    """Console-script entry point."""
    one_blas_thread()
    collector.collect_less_often()
    end(cli.main(args=argv, prog_name="ivslam", standalone_mode=False))


def one_blas_thread() -> None:
    """Ask OpenBLAS for one thread (unless ``OPENBLAS_NUM_THREADS`` says otherwise); NumPy,
    which reads it when first imported, is not imported yet.

    ivslam does no BLAS work (its kernels are numba loops), but NumPy's OpenBLAS starts a thread
    per further core when it loads, and each spins for up to ~0.1 s of CPU before it sleeps: on a
    machine whose other cores are busy (a batch of runs, a shared host), CPU taken from the run.
    """
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def end(code: int) -> NoReturn:
    """Exit the process with ``code`` once the command is done.

    Every output is closed by then (results are written and renamed, plots saved), so when no
    child process or other thread is left the process ends at once (``os._exit`` after flushing
    stdout and stderr): the interpreter's own teardown of the numba and LLVM modules costs
    ~0.4 s of wall time and does nothing for the user. Otherwise the usual ``sys.exit``.
    """
    import threading

    mp = sys.modules.get("multiprocessing")
    busy = bool(mp is not None and mp.active_children()) or any(
        t.is_alive() and not t.daemon for t in threading.enumerate() if t is not threading.main_thread())
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe (ivslam report | head) or a closed stream
            pass
    if busy:
        sys.exit(code)
    os._exit(code)


if __name__ == "__main__":  # pragma: no cover
    main(sys.argv[1:])
