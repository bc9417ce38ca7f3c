"""`ivslam report` (not implemented yet)."""

import click

from ivslam_cli.errors import IvslamError


@click.command(name="report")
def command() -> None:
    """Not available yet in this version."""
    raise IvslamError("'ivslam report' is not implemented yet in this version")
