"""`ivslam inspect` (not implemented yet)."""

import click

from ivslam_cli.errors import IvslamError


@click.command(name="inspect")
def command() -> None:
    """Not available yet in this version."""
    raise IvslamError("'ivslam inspect' is not implemented yet in this version")
