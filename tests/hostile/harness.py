"""Running ivslam as a hostile user would, and checking what it leaves.

:func:`cli` runs ``python -m ivslam_cli ARGS`` in a child process under a timeout (a hang is
a failure, not a stuck suite) and an address-space limit, and measures the child's peak
resident memory (``ru_maxrss`` from ``wait4``). :func:`expect_error` checks the contract for
bad input: exit 2 (3 under ``--strict``), one line ``ivslam: error: <file>: <problem>`` on
stderr, no traceback. :class:`Snapshot` proves that nothing but the expected outputs
changed in a directory and that no temporary file was left.
"""

from __future__ import annotations

import hashlib
import os
import resource
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
PY = sys.executable
GiB = 1 << 30
#: the address space a child may map (numba and LLVM reserve far more than they use)
AS_LIMIT = 8 * GiB
#: the peak resident memory any hostile input may cost (the issue's bound for bomb cases)
RSS_LIMIT = 1.5 * GiB


@dataclass
class Run:
    args: list[str]
    code: int
    out: str
    err: str
    seconds: float
    peak_rss: int  # bytes
    timed_out: bool = False
    signal: int = 0

    @property
    def lines(self) -> list[str]:
        return [ln for ln in self.err.splitlines() if ln.strip()]

    def __str__(self) -> str:
        return (f"ivslam {' '.join(self.args)} -> exit {self.code} in {self.seconds:.1f} s, "
                f"{self.peak_rss / 2**20:.0f} MiB\nstderr: {self.err[-2000:]}\nstdout: {self.out[-500:]}")


def _env(extra: dict | None) -> dict:
    env = dict(os.environ)
    env.setdefault("NUMBA_CACHE_DIR", str(Path(tempfile.gettempdir()) / "nc-hostile"))
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    env.pop("IVSLAM_LIMIT_TEXT_BYTES", None)
    env.update(extra or {})
    return env


# A forked child's peak RSS (ru_maxrss) starts at its parent's: Linux keeps the pre-exec image's
# high-water mark across exec, and a child forked from a pytest process of 1 GB would report
# 1 GB. The command therefore runs as a grandchild forked from this small launcher (a fresh
# signal struct, a small pre-exec image); the launcher forwards signals, reports the
# grandchild's ru_maxrss through a file and ends as it ended.
_LAUNCH = r"""
import os, signal, sys
out, argv = sys.argv[1], sys.argv[2:]
pid = os.fork()
if pid == 0:
    os.execv(argv[0], argv)
for s in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
    signal.signal(s, lambda n, f: os.kill(pid, n))
while True:
    try:
        _, status, usage = os.wait4(pid, 0)
        break
    except InterruptedError:
        continue
with open(out, "w") as f:
    f.write(str(usage.ru_maxrss))
if os.WIFSIGNALED(status):
    signal.signal(os.WTERMSIG(status), signal.SIG_DFL)
    os.kill(os.getpid(), os.WTERMSIG(status))
sys.exit(os.waitstatus_to_exitcode(status))
"""


def spawn(argv: list[str], *, timeout: float = 60, env: dict | None = None, cwd: Path | None = None,
          as_limit: int = AS_LIMIT, fsize: int | None = None, stdin=subprocess.DEVNULL,
          on_start=None) -> Run:
    """Run ``argv`` (a full command line) with the limits; ``on_start(proc)`` may signal it.
    ``peak_rss`` is the command's own peak resident memory."""

    def limits():
        os.setsid()
        resource.setrlimit(resource.RLIMIT_AS, (as_limit, as_limit))
        if fsize is not None:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails: EFBIG
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))

    argv = [str(a) for a in argv]
    with tempfile.TemporaryFile() as fo, tempfile.TemporaryFile() as fe, \
            tempfile.NamedTemporaryFile("r", suffix=".rss") as fr:
        t0 = time.perf_counter()
        p = subprocess.Popen([PY, "-S", "-c", _LAUNCH, fr.name, *argv], stdout=fo, stderr=fe, stdin=stdin,
                             env=_env(env), cwd=cwd or REPO, preexec_fn=limits)
        timed_out = threading.Event()

        def kill():
            timed_out.set()
            try:
                os.killpg(p.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass

        timer = threading.Timer(timeout, kill)
        timer.start()
        try:
            if on_start is not None:
                on_start(p)
            p.wait()
        finally:
            timer.cancel()
        seconds = time.perf_counter() - t0
        fo.seek(0)
        fe.seek(0)
        out, err = fo.read().decode("utf-8", "replace"), fe.read().decode("utf-8", "replace")
        fr.seek(0)
        text = fr.read().strip()
        peak = int(text) * 1024 if text else 0
    sig = -p.returncode if p.returncode < 0 else 0
    return Run(argv, p.returncode, out, err, seconds, peak, timed_out.is_set(), sig)


def cli(*args, timeout: float = 60, **kw) -> Run:
    """``python -m ivslam_cli ARGS`` under the limits (see :func:`spawn`)."""
    argv = [PY, "-m", "ivslam_cli", *(str(a) for a in args)]
    run = spawn(argv, timeout=timeout, **kw)
    run.args = [str(a) for a in args]
    return run


def expect_error(run: Run, about: str | Path | None = None, code: int = 2, contains: str | None = None) -> str:
    """The bad-input contract: ``code``, one ``ivslam: error:`` line naming ``about``, no traceback."""
    assert not run.timed_out, f"hung (killed after the timeout): {run}"
    assert run.code == code, f"expected exit {code}: {run}"
    assert "Traceback" not in run.err and "Traceback" not in run.out, str(run)
    errors = [ln for ln in run.lines if ln.startswith("ivslam: error: ")]
    assert len(errors) == 1 and run.lines[-1] == errors[0], f"not one error line: {run}"
    assert all(not ln.startswith("ivslam:") or ln == errors[0] or ln.startswith("ivslam: note:")
               for ln in run.lines), str(run)
    line = errors[0]
    if about is not None:
        assert line.startswith(f"ivslam: error: {about}: "), f"does not name {about}: {line}"
    if contains is not None:
        assert contains in line, f"{contains!r} not in: {line}"
    assert "internal error" not in line and ".tmp" not in line, line
    return line


def expect_ok_or_error(run: Run, about: str | Path | None = None) -> None:
    """Either a correct run (exit 0) or the bad-input contract; never a crash or a hang."""
    assert not run.timed_out, f"hung: {run}"
    if run.code == 0:
        assert "Traceback" not in run.err, str(run)
        return
    expect_error(run, about)


def inproc(*args, timeout: float = 60) -> Run:
    """``ivslam ARGS`` in this process (fast, for the generated corpus), under a SIGALRM
    timeout; peak memory is not measured here."""
    from click.testing import CliRunner

    from ivslam_cli.cli import cli as group

    def boom(*_):
        raise TimeoutError("hung")

    old = signal.signal(signal.SIGALRM, boom)
    signal.setitimer(signal.ITIMER_REAL, timeout)
    t0 = time.perf_counter()
    timed_out = False
    try:
        res = CliRunner().invoke(group, [str(a) for a in args])
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    if isinstance(res.exception, TimeoutError):
        timed_out = True
    err = res.stderr
    if res.exception is not None and not isinstance(res.exception, SystemExit):
        import traceback

        err += "".join(traceback.format_exception(res.exception))
    return Run([str(a) for a in args], res.exit_code, res.stdout, err, time.perf_counter() - t0, 0, timed_out)


# ------------------------------------------------------------------------ directories
def _digest(p: Path) -> str:
    h = hashlib.sha256()
    with open(p, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


class Snapshot:
    """What a directory holds (names, types, sizes, content hashes), to compare after a run."""

    def __init__(self, root: Path):
        self.root = Path(root)
        self.state = self._take()

    def _take(self) -> dict[str, tuple]:
        out = {}
        for dirpath, dirnames, filenames in os.walk(self.root):
            for name in dirnames + filenames:
                p = Path(dirpath) / name
                rel = str(p.relative_to(self.root))
                st = os.lstat(p)
                if p.is_symlink():
                    out[rel] = ("link", os.readlink(p))
                elif p.is_file():
                    out[rel] = ("file", st.st_size, _digest(p))
                elif p.is_dir():
                    out[rel] = ("dir",)
                else:
                    out[rel] = ("special", st.st_mode, st.st_rdev)
        return out

    def changes(self) -> tuple[set[str], set[str], set[str]]:
        """(added, removed, changed) relative paths since the snapshot."""
        now = self._take()
        added = set(now) - set(self.state)
        removed = set(self.state) - set(now)
        changed = {k for k in set(now) & set(self.state) if now[k] != self.state[k]}
        return added, removed, changed

    def assert_unchanged(self, allow_added: set[str] = frozenset()) -> None:
        added, removed, changed = self.changes()
        temps = {a for a in added if Path(a).name.startswith(".")}
        assert not temps, f"temporary files left: {sorted(temps)}"
        assert not removed and not changed, f"removed {sorted(removed)}, changed {sorted(changed)}"
        assert added <= set(allow_added), f"unexpected new files: {sorted(added - set(allow_added))}"
