"""The command group itself: help, version, cold start, the error policy."""

from __future__ import annotations

import subprocess
import sys

from ivslam_cli import __version__
from tests.helpers.paths import REPO


def test_version(cli_run):
    res = cli_run("--version")
    assert res.exit_code == 0
    assert __version__ in res.output


def test_help_lists_every_command(cli_run):
    res = cli_run("--help")
    assert res.exit_code == 0
    for name in ("run", "report", "simulate", "inspect"):
        assert name in res.output


def test_every_command_has_help_with_example(cli_run):
    for name in ("run", "report", "simulate", "inspect"):
        res = cli_run(name, "--help")
        assert res.exit_code == 0, res.output
        assert "ivslam " + name in res.output, f"{name} --help shows no example"


def test_help_is_cold_fast_and_loads_no_kernel():
    code = (
        "import sys, time; t=time.perf_counter();"
        "from ivslam_cli.cli import cli;"
        "import click.testing as ct; r=ct.CliRunner().invoke(cli,['--help']);"
        "assert r.exit_code==0;"
        "print(time.perf_counter()-t, 'numba' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    seconds, numba_loaded = out.stdout.split()
    assert numba_loaded == "False"
    assert float(seconds) < 0.5


def test_unknown_command_fails_cleanly(cli_run):
    res = cli_run("frobnicate")
    assert res.exit_code != 0
    assert "Traceback" not in res.output


def test_readme_generated_docs_are_current():
    """docs/config.md and docs/schema.md are generated from the code: never stale."""
    out = subprocess.run([sys.executable, str(REPO / "scripts" / "sync_docs.py"), "--check"],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr


def test_readme_and_docs_relative_links_exist():
    """Every relative link in README.md and docs/*.md points to a file (or directory) that exists."""
    import re
    from pathlib import Path

    repo = Path(__file__).resolve().parents[2]
    pages = [repo / "README.md", *sorted((repo / "docs").glob("*.md"))]
    assert len(pages) > 1, "docs/ has no pages"
    link = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
    broken = []
    for page in pages:
        text = page.read_text(encoding="utf-8")
        text = re.sub(r"^(```|~~~).*?^\1", "", text, flags=re.S | re.M)  # fenced code blocks
        text = re.sub(r"`[^`\n]*`", "", text)  # inline code
        for target in link.findall(text):
            if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I) or target.startswith("#"):
                continue  # URLs, mailto:, anchors within the page
            path = target.split("#", 1)[0].split("?", 1)[0]
            if not (page.parent / path).exists():
                broken.append(f"{page.relative_to(repo)}: {target}")
    assert not broken, "broken relative links:\n" + "\n".join(broken)
