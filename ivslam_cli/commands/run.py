"""`ivslam run` (not implemented yet)."""

import click

from ivslam_cli.errors import IvslamError


@click.command(name="run")
def command() -> None:
    """Not available yet in this version."""
    raise IvslamError("'ivslam run' is not implemented yet in this version")
