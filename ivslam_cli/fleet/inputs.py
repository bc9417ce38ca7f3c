"""The inputs of a batch: LOG arguments, directories of logs and manifests, expanded into entries.

- A **log** is anything a reader recognises, files and directories (a ROS 2 bag directory,
  an MRCLAM dataset) alike.
- A **directory** that is not itself a log stands for every log directly inside it (files
  and log directories, sorted by name), those a reader recognises by their name and first
  bytes; hidden files, ivslam results and fleet audits, and files no reader recognises are
  skipped. A directory with no log in it is an error.
- A **manifest** is a text file that is not a log, one log a line (``#`` starts a comment),
  a path relative to the manifest's directory, optionally followed by per-log overrides:
  ``--robot N|all``, ``--config FILE``, ``--mode MODE``. A line may name a directory (every
  log in it).

Nothing is opened before it is known to be a regular file (never a FIFO or a device).
"""

from __future__ import annotations

import os
import shlex
import stat
from dataclasses import dataclass
from pathlib import Path

from ivslam_cli.errors import IvslamError

MANIFEST_OPTIONS = ("--robot", "--config", "--mode")


@dataclass(frozen=True)
class Entry:
    """One log of a batch, with its per-log overrides (None: the command's own)."""

    path: Path
    label: str  # as the user (or the manifest) named it
    robot: int | str | None = None
    config_file: str | None = None
    mode: str | None = None


def _mode(path: Path) -> int | None:
    try:
        return os.stat(path).st_mode
    except OSError:
        return None


def log_directory(path: Path) -> bool:
    """True if the directory ``path`` is itself a log (ROS 2 bag, MRCLAM dataset)."""
    if (path / "metadata.yaml").is_file():
        return True
    return (path / "Barcodes.dat").is_file() or (path / "Barcodes.dat.xz").is_file()


def is_log_file(path: Path) -> bool:
    """True if a reader recognises the regular file ``path`` (and it is not an ivslam output)."""
    from ivslam_cli.atomic import written_by_ivslam
    from ivslam_cli.logs.detect import detect_format

    try:
        fmt = detect_format(path)
    except (IvslamError, OSError, ValueError, UnicodeDecodeError, EOFError):
        return False
    if fmt == "ivslam-h5":
        return written_by_ivslam(path) == "log"
    return True


def logs_in(directory: Path) -> list[Path]:
    """Every log directly inside ``directory`` (see the module docstring), sorted by name."""
    try:
        names = sorted(os.listdir(directory))
    except OSError as exc:
        raise IvslamError(f"cannot list the directory: {exc.strerror or exc}", directory) from None
    found = []
    for name in names:
        if name.startswith("."):
            continue
        p = directory / name
        mode = _mode(p)
        if mode is None:
            continue
        if stat.S_ISDIR(mode):
            if log_directory(p):
                found.append(p)
        elif stat.S_ISREG(mode) and is_log_file(p):
            found.append(p)
    return found


def is_manifest(path: Path) -> bool:
    """A regular text file no reader recognises whose first entry names an existing path."""
    mode = _mode(path)
    if mode is None or not stat.S_ISREG(mode) or is_log_file(path):
        return False
    try:
        with open(path, "rb") as f:
            head = f.read(1 << 16)
    except OSError:
        return False
    if b"\x00" in head:
        return False
    try:
        text = head.decode("utf-8")
    except UnicodeDecodeError:
        return False
    for line in text.splitlines():
        try:
            tokens = shlex.split(line, comments=True)
        except ValueError:
            return False
        if tokens:
            first = Path(tokens[0]).expanduser()
            return os.path.lexists(first if first.is_absolute() else path.parent / first)
    return False


def read_manifest(path: Path) -> list[Entry]:
    """The entries of a manifest; a malformed line is a one-line error naming ``path:line``."""
    from ivslam_cli.slam import MODES

    entries: list[Entry] = []
    text = path.read_text(encoding="utf-8")
    for n, line in enumerate(text.splitlines(), 1):
        where = f"{path}:{n}"
        try:
            tokens = shlex.split(line, comments=True)
        except ValueError as exc:
            raise IvslamError(f"cannot parse the manifest line ({exc})", where) from None
        if not tokens:
            continue
        log = Path(tokens[0]).expanduser()
        log = log if log.is_absolute() else path.parent / log
        over: dict[str, object] = {}
        rest = tokens[1:]
        while rest:
            opt, *rest = rest
            if "=" in opt and opt.startswith("--"):
                opt, value = opt.split("=", 1)
            elif rest:
                value, *rest = rest
            else:
                raise IvslamError(f"{opt} needs a value", where)
            if opt not in MANIFEST_OPTIONS:
                raise IvslamError(f"unknown per-log option {opt!r} (a manifest line takes "
                                  f"{', '.join(MANIFEST_OPTIONS)})", where)
            if opt == "--robot":
                if value != "all":
                    try:
                        value = int(value)
                    except ValueError:
                        raise IvslamError(f"--robot {value!r} is neither a robot number nor 'all'", where) from None
                over["robot"] = value
            elif opt == "--config":
                cfg = Path(value).expanduser()
                over["config_file"] = str(cfg if cfg.is_absolute() else path.parent / cfg)
            else:
                if value not in (*MODES, "auto"):
                    raise IvslamError(f"--mode {value!r} is not one of {', '.join((*MODES, 'auto'))}", where)
                over["mode"] = value
        mode = _mode(log)
        if mode is not None and stat.S_ISDIR(mode) and not log_directory(log):
            found = logs_in(log)
            if not found:
                raise IvslamError("no log in this directory that a reader recognises", log)
            entries.extend(Entry(p, str(p), **over) for p in found)
        else:
            entries.append(Entry(log, tokens[0], **over))
    if not entries:
        raise IvslamError("the manifest names no log", path)
    return entries


def single_log(args: tuple[str, ...]) -> bool:
    """True if ``args`` is one log (not a directory of logs, not a manifest)."""
    if len(args) != 1:
        return False
    p = Path(args[0])
    mode = _mode(p)
    if mode is None:
        return True  # missing: the reader says so, as for any log
    if stat.S_ISDIR(mode):
        return log_directory(p)
    return not is_manifest(p)


def expand(args: tuple[str, ...]) -> list[Entry]:
    """The entries of a batch, in the order given (a directory's logs by name)."""
    entries: list[Entry] = []
    for arg in args:
        p = Path(arg)
        mode = _mode(p)
        if mode is not None and stat.S_ISDIR(mode) and not log_directory(p):
            found = logs_in(p)
            if not found:
                raise IvslamError("no log in this directory that a reader recognises", p)
            entries.extend(Entry(f, str(f)) for f in found)
        elif mode is not None and stat.S_ISREG(mode) and is_manifest(p):
            entries.extend(read_manifest(p))
        else:
            entries.append(Entry(p, arg))
    return entries


def result_name(entry: Entry, robot: int | str | None) -> str:
    """The result's name in the output directory, without ``.MODE.h5``: the log's name before
    its first dot, and its robot when one is given."""
    base = Path(str(entry.path).rstrip("/")).name.split(".")[0] or "log"
    return base if robot is None else f"{base}.robot{robot}"
