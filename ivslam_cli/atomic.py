"""Atomic outputs: a file or a directory is written under a temporary name beside its final
path, then renamed into place, so a reader sees either the old state or the complete new
output, never a partial one.

What an output may replace (checked before any work starts, and again at the rename):

- without ``force``, nothing: an existing path is refused with :data:`EXISTS`, and the final
  rename is exclusive (``renameat2(RENAME_NOREPLACE)``, or a hard link), so two processes
  writing the same new path cannot both succeed;
- with ``force``, only a previous output of ivslam of the same kind (a result, a log, a TUM
  trajectory, a map, a plot: :func:`written_by_ivslam`), never a special file (FIFO, device,
  socket), a directory where a file is written, a file ivslam did not write, or an input of
  the command (or a path inside or around one);
- one command never writes two outputs to one path.

A command with several outputs writes them in one :func:`transaction`: each is written to its
temporary, and only when all are complete are they renamed into place; if any fails, none is
left (the replaced ones are restored). Write errors (disk full, I/O error) are one-line
:class:`OutputError`\\ s naming the final path, never the temporary one. :func:`refuse_existing`
is the early check a command makes before it starts work.
"""

from __future__ import annotations

import contextlib
import contextvars
import ctypes
import errno
import os
import shutil
import stat
import tempfile
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from ivslam_cli.errors import IvslamError, OutputError
from ivslam_cli.inputs import same_or_inside, special_kind

EXISTS = "already exists; refusing to overwrite it (use --force)"
TWICE = "is given as two outputs of this command: refusing to write both to one path"
NOT_OURS = "exists and is not {what} written by ivslam; refusing to replace it, even with --force"

#: kinds of output, as :func:`written_by_ivslam` recognises them
KINDS = {"result": "a result", "log": "a log", "tum": "a TUM trajectory",
         "pgm": "a map_server PGM map", "map-yaml": "a map_server YAML file", "plot": "a plot",
         "fleet": "a fleet audit", "graph": "an interval pose graph", "g2o": "a g2o pose graph"}

# errors of the device rather than of the path given (exit 1)
_IO_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.EFBIG, errno.ENOMEM, errno.EROFS}


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


# --------------------------------------------------------------------------- ownership
def _head(path: Path, n: int) -> bytes:
    try:
        with open(path, "rb") as f:
            return f.read(n)
    except OSError:
        return b""


def _tail(path: Path, n: int) -> bytes:
    try:
        with open(path, "rb") as f:
            f.seek(0, os.SEEK_END)
            size = f.tell()
            f.seek(max(0, size - n))
            return f.read(n)
    except OSError:
        return b""


def written_by_ivslam(path: str | Path) -> str | None:
    """The kind of output (a key of :data:`KINDS`) ``path`` is, if ivslam wrote it; else None.

    Recognised: results and logs in HDF5 (their format attributes), MCAP logs (the header's
    library), ROS 1 bags and ROS 2 bag directories with ivslam's ``/ivslam/meta`` topic, TUM
    trajectories, map_server maps and fleet audits (the header and layout ivslam writes), plots (the
    ``ivslam`` marker in their metadata).
    """
    path = Path(path)
    try:
        st = os.stat(path)
    except OSError:
        return None
    if stat.S_ISDIR(st.st_mode):
        meta = path / "metadata.yaml"
        if meta.is_file() and b"/ivslam/meta" in _head(meta, 1 << 20):
            return "log"
        return None
    if not stat.S_ISREG(st.st_mode):
        return None
    head = _head(path, 4096)
    if head.startswith(b"\x89HDF\r\n\x1a\n"):
        try:
            import h5py

            with h5py.File(path, "r") as f:
                fmt = f.attrs.get("format")
                fmt = fmt.decode() if isinstance(fmt, bytes) else fmt
                if fmt == "ivslam-result":
                    return "result"
                if "ivslam_log_version" in f.attrs:
                    return "log"
        except Exception:  # noqa: BLE001 - unreadable: not provably ours
            return None
        return None
    if head.startswith(b"\x89MCAP0\r\n"):
        try:
            from mcap.reader import make_reader

            with open(path, "rb") as f:
                if make_reader(f).get_header().library.startswith("ivslam"):
                    return "log"
        except Exception:  # noqa: BLE001
            return None
        return None
    if head.startswith(b"#ROSBAG V2.0\n"):
        marker = b"topic=/ivslam/meta"
        return "log" if marker in head or marker in _tail(path, 1 << 20) else None
    if head.startswith(b"# timestamp x y z qx qy qz qw (centres of ivslam pose boxes)\n"):
        return "tum"
    if head.startswith(b'{\n  "format": "ivslam-fleet"') or head.startswith(b"# ivslam fleet audit: "):
        return "fleet"
    if head.startswith(b'{\n "format": "ivslam-interval-pose-graph"'):
        return "graph"
    if head.startswith(b"# ivslam pose graph centres (g2o)\n"):
        return "g2o"
    if head.startswith(b"P5\n# ivslam map\n"):
        return "pgm"
    if head.startswith(b"image: "):
        keys = [line.split(b":", 1)[0] for line in head.splitlines() if line.strip()]
        if keys == [b"image", b"mode", b"resolution", b"origin", b"negate", b"occupied_thresh",
                    b"free_thresh"]:
            return "map-yaml"
        return None
    if (head.startswith(b"\x89PNG") or b"<svg" in head) and b"ivslam" in head:
        return "plot"
    return None


# --------------------------------------------------------------------------- checks
def _parent(path: Path) -> Path:
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise IvslamError(f"directory {str(parent)!r} does not exist", path)
    if not os.access(parent, os.W_OK | os.X_OK):
        raise IvslamError(f"directory {str(parent)!r} is not writable", path)
    return parent


def check_output(path: str | Path, *, force: bool = False, kind: str | None = None,
                 inputs: Iterable[str | Path] = (), directory: bool = False) -> Path:
    """Refuse ``path`` as an output (one-line :class:`IvslamError`) unless it may be written.

    ``kind`` is what will be written there (see :data:`KINDS`; None: any ivslam output);
    ``directory`` says the output is a directory (a ROS 2 bag).
    """
    path = Path(path)
    for inp in inputs:
        if inp is not None and same_or_inside(path, inp):
            raise IvslamError(f"is an input of this command ({inp}), or inside or around one: "
                              "refusing to write an output there", path)
    _parent(path)
    if not os.path.lexists(path):
        return path
    try:
        st = os.stat(path)
    except OSError:  # a dangling symbolic link: replacing the link loses nothing
        if not force:
            raise IvslamError(EXISTS, path) from None
        return path
    special = special_kind(st.st_mode)
    if special is not None:
        raise IvslamError(f"is {special}, not a regular file: refusing to replace it", path)
    if stat.S_ISDIR(st.st_mode) and not directory:
        raise IvslamError("is a directory: refusing to replace it", path)
    if not force:
        raise IvslamError(EXISTS, path)
    found = written_by_ivslam(path)
    if found is None or (kind is not None and found != kind):
        what = KINDS.get(kind, "an output") if kind else "an output"
        if found is not None:
            raise IvslamError(f"is {KINDS[found]} written by ivslam, not {what}: refusing to "
                              "replace it, even with --force", path)
        raise IvslamError(NOT_OURS.format(what=what), path)
    return path


def refuse_existing(path: str | Path, force: bool, *, kind: str | None = None,
                    inputs: Iterable[str | Path] = ()) -> None:
    """The early check of an output (before a command starts its work): see
    :func:`check_output`. Inside a :func:`transaction` the path is also planned, so two
    outputs on one path are refused."""
    txn = _TXN.get()
    if txn is not None:
        txn.plan(Path(path))
        inputs = (*inputs, *txn.inputs)
    check_output(path, force=force, kind=kind, inputs=inputs)


def _prepare(path: Path, force: bool, kind: str | None, directory: bool) -> Path:
    """Checks before writing ``path``; returns its directory."""
    txn = _TXN.get()
    inputs: tuple = ()
    if txn is not None:
        txn.claim(path)
        inputs = txn.inputs
    check_output(path, force=force, kind=kind, inputs=inputs, directory=directory)
    return _parent(path)


# --------------------------------------------------------------------------- renames
_RENAME_NOREPLACE = 1
_AT_FDCWD = -100


def _renameat2():
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return None
    fn.argtypes = (ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint)
    fn.restype = ctypes.c_int
    return fn


_RENAMEAT2 = _renameat2()


def rename_noreplace(src: str | Path, dst: str | Path) -> None:
    """Rename ``src`` to ``dst``, failing with FileExistsError if ``dst`` exists (atomic)."""
    src, dst = os.fsencode(src), os.fsencode(dst)
    if _RENAMEAT2 is not None:
        if _RENAMEAT2(_AT_FDCWD, src, _AT_FDCWD, dst, _RENAME_NOREPLACE) == 0:
            return
        err = ctypes.get_errno()
        if err == errno.EEXIST:
            raise FileExistsError(err, os.strerror(err), os.fsdecode(dst))
        if err not in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP, errno.EPERM):
            raise OSError(err, os.strerror(err), os.fsdecode(dst))
    if os.path.isdir(src):  # no exclusive rename for directories here: check, then rename
        if os.path.lexists(dst):
            raise FileExistsError(errno.EEXIST, os.strerror(errno.EEXIST), os.fsdecode(dst))
        os.rename(src, dst)
        return
    os.link(src, dst)  # fails with EEXIST if dst exists
    os.unlink(src)


def _backup_name(path: Path) -> Path:
    fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".old", dir=path.parent)
    os.close(fd)
    os.unlink(name)
    return Path(name)


@dataclass
class _Staged:
    tmp: Path  # the complete output under its temporary name
    path: Path  # its final name
    force: bool
    kind: str | None
    cleanup: Path | None = None  # a temporary directory holding tmp, removed at the end
    backup: Path | None = None  # the replaced output, kept until the commit is complete
    done: bool = False


def _remove(p: Path | None) -> None:
    if p is None or not os.path.lexists(p):
        return
    if p.is_dir() and not p.is_symlink():
        shutil.rmtree(p, ignore_errors=True)
    else:
        with contextlib.suppress(OSError):
            os.unlink(p)


def _commit(item: _Staged, inputs) -> None:
    path = item.path
    if item.force and os.path.lexists(path):
        check_output(path, force=True, kind=item.kind, inputs=inputs, directory=item.tmp.is_dir())
        backup = _backup_name(path)
        if item.tmp.is_dir() or path.is_dir():
            os.rename(path, backup)
            item.backup = backup
            os.rename(item.tmp, path)
        else:
            try:
                os.link(path, backup)  # the old file stays whole at its name until the replace
            except OSError:
                os.rename(path, backup)
            item.backup = backup
            os.replace(item.tmp, path)
    else:
        try:
            rename_noreplace(item.tmp, path)
        except FileExistsError:
            raise IvslamError(EXISTS, path) from None
    item.done = True


def _rollback(item: _Staged) -> None:
    if item.done:
        if item.backup is not None:
            if item.path.is_dir() and not item.path.is_symlink():
                shutil.rmtree(item.path, ignore_errors=True)
            with contextlib.suppress(OSError):
                os.replace(item.backup, item.path)
        else:
            _remove(item.path)
    else:
        _remove(item.tmp)
    _remove(item.cleanup)


# --------------------------------------------------------------------------- transactions
@dataclass
class Transaction:
    """The outputs of one command, renamed into place together (see :func:`transaction`)."""

    force: bool = False
    inputs: tuple[Path, ...] = ()
    planned: set[Path] = field(default_factory=set)
    claimed: set[Path] = field(default_factory=set)
    staged: list[_Staged] = field(default_factory=list)

    @staticmethod
    def _key(path: Path) -> Path:
        return Path(os.path.abspath(path))

    def plan(self, path: Path) -> None:
        """An output the command will write (its early check): once per path."""
        key = self._key(path)
        if key in self.planned:
            raise IvslamError(TWICE, path)
        self.planned.add(key)

    def claim(self, path: Path) -> None:
        """An output being written now: once per path."""
        key = self._key(path)
        if key in self.claimed:
            raise IvslamError(TWICE, path)
        self.claimed.add(key)

    def commit(self) -> None:
        try:
            for item in self.staged:
                _commit(item, self.inputs)
        except BaseException:
            self.rollback()
            raise
        for item in self.staged:
            _remove(item.backup)
            _remove(item.cleanup)
        self.staged.clear()

    def rollback(self) -> None:
        for item in reversed(self.staged):
            _rollback(item)
        self.staged.clear()


_TXN: contextvars.ContextVar[Transaction | None] = contextvars.ContextVar("ivslam_txn", default=None)


@contextlib.contextmanager
def transaction(*, force: bool = False, inputs: Iterable[str | Path | None] = ()) -> Iterator[Transaction]:
    """Every :func:`atomic_path` / :func:`atomic_output` inside is renamed into place only
    when the block completes; on any error (or signal) none is left, and what they replaced
    is restored. ``inputs`` may not be written, replaced, or contain or lie around an output.
    Inside another transaction, the outputs join it (and its inputs grow by ``inputs``)."""
    outer = _TXN.get()
    if outer is not None:
        outer.inputs = (*outer.inputs, *(Path(p) for p in inputs if p is not None))
        yield outer
        return
    txn = Transaction(force=force, inputs=tuple(Path(p) for p in inputs if p is not None))
    token = _TXN.set(txn)
    try:
        yield txn
        txn.commit()
    except BaseException:
        txn.rollback()
        raise
    finally:
        _TXN.reset(token)


def output_error(exc: BaseException, path: Path) -> IvslamError | None:
    """The one-line error for a failure while writing ``path`` (None if it is not an I/O one)."""
    chain, seen = exc, 0
    while chain is not None and seen < 8:
        if isinstance(chain, IvslamError):
            return None
        if isinstance(chain, OSError) and chain.errno is not None:
            msg = f"cannot write: {chain.strerror or os.strerror(chain.errno)}"
            return (OutputError if chain.errno in _IO_ERRNOS else IvslamError)(msg, path)
        text = str(chain).lower()
        if "disk is full" in text or "no space left" in text:
            return OutputError(f"cannot write: {os.strerror(errno.ENOSPC)}", path)
        if "disk i/o error" in text:  # sqlite3's word for a failed write (full disk, size limit)
            return OutputError("cannot write: disk I/O error (a full disk or a file size limit?)", path)
        chain = chain.__cause__ or chain.__context__
        seen += 1
    return None


def _finish(item: _Staged) -> None:
    """Commit ``item`` now, or hand it to the enclosing transaction."""
    txn = _TXN.get()
    if txn is not None:
        txn.staged.append(item)
        return
    try:
        _commit(item, ())
    except BaseException:
        _rollback(item)
        raise
    _remove(item.backup)
    _remove(item.cleanup)


def _finish_or_remove(item: _Staged) -> None:
    """:func:`_finish`, and if anything (a signal) interrupts it, the temporary goes too."""
    try:
        _finish(item)
    except BaseException:
        if not item.done:
            _remove(item.tmp)
            _remove(item.cleanup)
        raise


@contextlib.contextmanager
def atomic_path(path: str | Path, *, force: bool = False, kind: str | None = None) -> Iterator[Path]:
    """Yield a temp file path next to ``path``; on success it is renamed onto ``path`` (at
    the end of the enclosing :func:`transaction`, if any).

    On any exception the temp file is removed and ``path`` is left untouched.
    """
    path = Path(path)
    parent = _prepare(path, force, kind, directory=False)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=parent)
    except OSError as exc:
        raise (output_error(exc, path) or exc) from None
    os.close(fd)
    tmp = Path(tmp)
    try:
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; outputs get the usual mode
        yield tmp
    except BaseException as exc:
        _remove(tmp)
        err = output_error(exc, path) if isinstance(exc, Exception) else None
        if err is not None:
            raise err from None
        raise
    _finish_or_remove(_Staged(tmp=tmp, path=path, force=force, kind=kind))


@contextlib.contextmanager
def atomic_output(path: str | Path, *, force: bool = False, kind: str | None = None) -> Iterator[Path]:
    """Yield a path to write, a file or a directory (a ROS 2 bag), that is renamed to
    ``path`` on success.

    The temporary lives in a fresh directory beside ``path`` (same file system), so the final
    rename is atomic; on error nothing is left behind and ``path`` is untouched.
    """
    path = Path(path)
    parent = _prepare(path, force, kind, directory=True)
    try:
        tmpdir = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmp", dir=parent))
    except OSError as exc:
        raise (output_error(exc, path) or exc) from None
    target = tmpdir / path.name
    try:
        yield target
        if not target.exists():
            raise IvslamError("writer produced no output", path)
        if os.path.lexists(path) and os.path.isdir(path) != target.is_dir():
            raise IvslamError("exists as a " + ("directory" if os.path.isdir(path) else "file")
                              + ": refusing to replace it by a " + ("directory" if target.is_dir() else "file"),
                              path)
    except BaseException as exc:
        shutil.rmtree(tmpdir, ignore_errors=True)
        err = output_error(exc, path) if isinstance(exc, Exception) else None
        if err is not None:
            raise err from None
        raise
    _finish_or_remove(_Staged(tmp=target, path=path, force=force, kind=kind, cleanup=tmpdir))


def write_text_atomic(path: str | Path, text: str, *, force: bool = False, kind: str | None = None) -> None:
    with atomic_path(path, force=force, kind=kind) as tmp:
        tmp.write_text(text, encoding="utf-8")


def write_bytes_atomic(path: str | Path, data: bytes, *, force: bool = False, kind: str | None = None) -> None:
    with atomic_path(path, force=force, kind=kind) as tmp:
        tmp.write_bytes(data)
