"""A run directory's files: its lock, its records (read, repaired, appended) and atomic rewrites.

``OUT/.lock`` holds the running driver's PID and host, so a second run on the same directory refuses
and a lock left by a killed run (its PID gone from this host) is taken over. Records are appended
with one ``write`` each and cut back on error, so a full disk never leaves half a record behind.
"""

from __future__ import annotations

import errno
import json
import os
import secrets
import socket
from collections.abc import Callable
from pathlib import Path
from typing import Any

from navbench.safeio import InputTooLarge, read_input, write_private

_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)


class RunError(ValueError):
    """A run cannot start or continue (bad config, incompatible resume); the message says why."""


def _oserror(path: Path, exc: OSError, doing: str) -> RunError:
    return RunError(f"{path}: cannot {doing}: {exc.strerror or exc}")


def _pid_alive(pid: int) -> bool:
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # alive, owned by someone else
        return True
    return True


def _create_exclusive(path: Path, text: str) -> bool:
    """Write ``text`` to ``path`` only if it does not exist (the lock appears whole or not at all)."""
    tmp = path.with_name(f"{path.name}.{os.getpid()}.{secrets.token_hex(4)}")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW, 0o644)  # never through a planted link
    with os.fdopen(fd, "w") as fh:
        fh.write(text)
    try:
        os.link(tmp, path)
        return True
    except FileExistsError:
        return False
    finally:
        tmp.unlink(missing_ok=True)


class RunLock:
    """``OUT/.lock`` for the lifetime of a run; ``note`` hears about a stale lock taken over."""

    def __init__(self, out: Path, note: Callable[[str], None]) -> None:
        self.path = Path(out) / ".lock"
        self.host = socket.gethostname()
        self.text = json.dumps({"pid": os.getpid(), "host": self.host}) + "\n"
        try:
            for _ in range(3):
                if _create_exclusive(self.path, self.text):
                    return
                holder = self._holder()
                if holder == {}:  # released meanwhile
                    continue
                if holder is None or (holder.get("host") == self.host and not _pid_alive(int(holder["pid"]))):
                    who = "unreadable" if holder is None else f"PID {holder['pid']} is not running"
                    note(f"{self.path}: taking over a stale lock ({who}: a run killed before it finished)")
                    self.path.unlink(missing_ok=True)
                    continue
                raise RunError(f"{out}: another run is using this directory (PID {holder['pid']} on "
                               f"{holder.get('host')}, {self.path}); wait for it, or delete the lock if it is gone")
        except OSError as exc:
            raise _oserror(Path(out), exc, "create the run's lock file") from None
        raise RunError(f"{self.path}: could not take the lock")

    def _holder(self) -> dict[str, Any] | None:
        try:
            holder = json.loads(self.path.read_text())
            int(holder["pid"])
            return holder
        except FileNotFoundError:
            return {}
        except (ValueError, KeyError, TypeError):
            return None

    def release(self) -> None:
        try:
            if self.path.read_text() == self.text:
                self.path.unlink()
        except OSError:
            pass


def write_atomic(path: Path, text: str) -> None:
    """Replace ``path`` by ``text`` whole: a crash leaves the old file or the new one, never a mix. The
    temporary file is created new and never through a symlink (see :func:`navbench.safeio.write_private`)."""
    try:
        write_private(path, text)
    except OSError as exc:
        raise _oserror(path, exc, "write") from None


def read_records(path: Path, notes: list[str] | None = None) -> list[dict[str, Any]]:
    """Records of ``episodes.jsonl``; a truncated last line (a run killed mid-write) is dropped (and
    noted in ``notes``); a corrupt line elsewhere is an error."""
    if not path.is_file():
        return []
    try:
        lines = read_input(path).decode("utf-8", "replace").splitlines()
    except InputTooLarge as exc:
        raise RunError(str(exc)) from None
    records = []
    for i, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            records.append(json.loads(line))
        except (json.JSONDecodeError, RecursionError):
            if i == len(lines) - 1:
                if notes is not None:
                    notes.append(f"{path}: dropped a truncated last line (an episode cut off mid-write; rerun)")
                break
            raise RunError(f"{path}: line {i + 1} is corrupt") from None
    return records


def record_line(record: dict[str, Any]) -> bytes:
    return (json.dumps(record, allow_nan=False) + "\n").encode()


def _write(fd: int, data: bytes) -> int:
    return os.write(fd, data)


class RecordFile:
    """``episodes.jsonl`` opened for appending; each record is written, flushed and synced whole."""

    def __init__(self, path: Path) -> None:
        self.path = path
        try:
            self.fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | _NOFOLLOW, 0o644)
        except OSError as exc:
            raise _oserror(path, exc, "open for appending") from None

    def append(self, record: dict[str, Any]) -> None:
        data = record_line(record)
        start = os.lseek(self.fd, 0, os.SEEK_END)
        try:
            done = 0
            while done < len(data):
                done += _write(self.fd, data[done:])
            os.fsync(self.fd)
        except OSError as exc:
            try:  # no half record left behind: the episode is rerun by --resume
                os.ftruncate(self.fd, start)
            except OSError:
                pass
            what = "disk full" if exc.errno == errno.ENOSPC else (exc.strerror or str(exc))
            raise RunError(f"{self.path}: cannot append episode {record.get('episode_id')}: {what}; finished "
                           f"episodes are kept (free space, then rerun with --resume)") from None

    def close(self) -> None:
        os.close(self.fd)


def make_run_dir(out: Path) -> None:
    """Create a run directory (and its parents), or say in one line why it cannot be."""
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RunError(f"{out}: cannot create the run directory: {exc.strerror or exc}") from None
