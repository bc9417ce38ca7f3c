"""`ivslam simulate` (not implemented yet)."""

import click

from ivslam_cli.errors import IvslamError


@click.command(name="simulate")
def command() -> None:
    """Not available yet in this version."""
    raise IvslamError("'ivslam simulate' is not implemented yet in this version")
