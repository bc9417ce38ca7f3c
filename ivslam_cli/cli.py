"""The ``ivslam`` command group: thin entry points, one module per command.

Each command lives in ``ivslam_cli/commands/<name>.py`` and is imported only when it is
invoked (or when ``--help`` lists it), so ``ivslam --help`` never loads numba kernels.
Errors a user can cause become one line on stderr and a non-zero exit; ``--debug``
shows the traceback instead.
"""

from __future__ import annotations

import importlib
import sys

import click

from ivslam_cli import __version__

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
        from ivslam_cli.errors import IvslamError

        try:
            return super().invoke(ctx)
        except (click.ClickException, click.exceptions.Exit, click.exceptions.Abort):
            raise
        except IvslamError as exc:
            if ctx.obj and ctx.obj.get("debug"):
                raise
            raise UserError(str(exc), exc.exit_code) from exc
        except KeyboardInterrupt:
            raise click.exceptions.Abort() from None
        except OSError as exc:
            if ctx.obj and ctx.obj.get("debug"):
                raise
            where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
            raise UserError(f"{where}{exc.strerror or exc}", 1) from exc
        except Exception as exc:  # last resort: still one line, but say it is ours
            if ctx.obj and ctx.obj.get("debug"):
                raise
            raise UserError(
                f"internal error ({type(exc).__name__}: {exc}); rerun with --debug for a traceback",
                1,
            ) from exc


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


def main(argv: list[str] | None = None) -> None:
    """Console-script entry point."""
    cli.main(args=argv, prog_name="ivslam")


if __name__ == "__main__":  # pragma: no cover
    main(sys.argv[1:])
