"""Keep the generated parts of README.md in sync with the code.

    python scripts/sync_readme.py          # rewrite README.md
    python scripts/sync_readme.py --check  # exit 1 if README.md is stale (used by the tests)

Generated sections: the configuration table (``ivslam_cli.config.markdown_table``) and the
HDF5 result schema (``ivslam_cli/results/SCHEMA.md``).
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from ivslam_cli.config import markdown_table  # noqa: E402


def sections() -> dict[str, str]:
    return {
        "config-table": markdown_table().strip(),
        "result-schema": (REPO / "ivslam_cli" / "results" / "SCHEMA.md").read_text(encoding="utf-8").strip(),
    }


def render(text: str) -> str:
    for name, body in sections().items():
        pattern = re.compile(rf"(<!-- BEGIN {re.escape(name)}[^>]*-->\n).*?(<!-- END {re.escape(name)} -->)", re.S)
        if not pattern.search(text):
            raise SystemExit(f"README.md has no '{name}' markers")
        text = pattern.sub(lambda m: m.group(1) + body + "\n" + m.group(2), text)
    return text


def main(argv: list[str]) -> int:
    readme = REPO / "README.md"
    old = readme.read_text(encoding="utf-8")
    new = render(old)
    if "--check" in argv:
        if new != old:
            print("README.md is stale: run python scripts/sync_readme.py")
            return 1
        return 0
    readme.write_text(new, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
