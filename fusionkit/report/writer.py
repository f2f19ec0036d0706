"""Output folders that never lose a user's file.

`--out DIR` may be replaced only when DIR is absent, empty, or an earlier fusionkit output: a folder
holding the marker file `.fusionkit-output`, which lists the entries fusionkit wrote there. DIR may
never be, or contain, one of the run's inputs (config, robot descriptions, data, truth).

Everything is written into a temporary folder inside DIR; only when all of it succeeded do the new
entries replace the ones the marker lists. Entries the marker does not list (a file the user added
later) are left where they are; one whose name an output needs is refused before any work. On any
error the temporary folder, and DIR itself if this call created it, are removed.
"""

from __future__ import annotations

import json
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterable, Iterator

from .. import __version__
from ..errors import FusionkitError, PluginError

MARKER = ".fusionkit-output"
TEMP_PREFIX = ".fusionkit-tmp-"


def _error(out: Path, why: str) -> FusionkitError:
    return FusionkitError(f"--out {out}: {why}")


def output_entries(folder: Path) -> set[str] | None:
    """Entries an earlier fusionkit output wrote into `folder`; None when it has no readable marker."""
    try:
        data = json.loads((folder / MARKER).read_text(encoding="utf-8"))
        return {str(e) for e in data["entries"]}
    except (OSError, ValueError, KeyError, TypeError):
        return None


def check_output_folder(out: Path, inputs: Iterable[Path] = ()) -> Path:
    """The absolute folder `out` if fusionkit may write it, else a FusionkitError saying why and what
    to do. Called before any work, and again just before the outputs are moved in."""
    folder = Path(out).expanduser().resolve()
    for part in (folder, *folder.parents):
        if part.exists():
            if not part.is_dir():
                where = "exists and is not a folder" if part == folder else f"is inside {part}, which is a file"
                raise _error(out, f"{where}; expected a folder path")
            break
    for item in inputs:
        item = Path(item).resolve()
        if item == folder or folder in item.parents:
            raise _error(out, f"the folder holds an input of this run ({item}); write the outputs elsewhere, "
                              "e.g. --out out/result")
    if not folder.exists():
        return folder
    entries = {p.name for p in folder.iterdir() if not p.name.startswith(TEMP_PREFIX)}
    if not entries:
        return folder
    owned = output_entries(folder)
    if owned is None:
        raise _error(out, f"the folder exists, is not empty and was not written by fusionkit (it has no "
                          f"{MARKER} file); choose a new or empty folder (nothing was changed)")
    return folder


@contextmanager
def atomic_directory(out: Path, command: str, inputs: Iterable[Path] = ()) -> Iterator[Path]:
    """Yield an empty temporary folder for the outputs of `command` (e.g. "run"); on success its
    entries replace those of the earlier fusionkit output in `out` and a marker listing them is
    written; on error nothing in `out` changes and no temporary folder remains."""
    folder = check_output_folder(out, list(inputs))
    created = [p for p in (folder, *folder.parents) if not p.exists()]
    folder.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=TEMP_PREFIX, dir=folder))
    try:
        yield tmp
        new = sorted(p.name for p in tmp.iterdir())
        _replace_entries(folder, tmp, new, out)
        (folder / MARKER).write_text(json.dumps({"written_by": f"fusionkit {command}",
                                                 "fusionkit_version": __version__, "entries": new}, indent=1)
                                     + "\n", encoding="utf-8")
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        for part in created:  # innermost first: only the folders this call made, now empty again
            try:
                part.rmdir()
            except OSError:
                break
        raise
    shutil.rmtree(tmp, ignore_errors=True)


def _replace_entries(folder: Path, tmp: Path, new: list[str], out: Path) -> None:
    """Move the earlier output's entries aside, the new ones in, then delete the earlier ones.
    A name the user put there (not in the marker) is never touched: writing over it is refused."""
    owned = output_entries(folder) or set()
    present = {p.name for p in folder.iterdir() if p != tmp and p.name != MARKER}
    clash = sorted(name for name in new if name in present and name not in owned)
    if clash:
        raise _error(out, f"{', '.join(clash)} in the folder was not written by fusionkit; move it or choose "
                          "another folder (nothing was changed)")
    old = tmp / ".old"
    old.mkdir()
    for name in owned & present:
        (folder / name).rename(old / name)
    for name in new:
        (tmp / name).rename(folder / name)


def write_error(out: Path, exc: OSError) -> FusionkitError:
    """The one-line error for an OSError while writing the outputs into `out`."""
    return FusionkitError(f"--out {out}: cannot write {exc.filename or out} ({exc.strerror or exc}); nothing was "
                          "written; expected a writable folder")


def write_files(folder: Path, files: dict[str, str | bytes], source: str) -> None:
    """Write {relative path: text or bytes} into `folder` (a fresh output folder), creating subfolders.
    A path that is absolute, leaves the folder (`..`) or names a file already written is a PluginError
    naming `source` (who produced the files, e.g. "robot model serial_arm")."""
    for name, content in files.items():
        rel = Path(name)
        if not name or rel.is_absolute() or ".." in rel.parts or rel.parts[0].startswith(TEMP_PREFIX) \
                or name == MARKER:
            raise PluginError(f"{source}: output file {name!r} is not a relative path inside the output folder")
        path = folder / rel
        if path.exists():
            raise PluginError(f"{source}: output file {name!r} is already written by another output")
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content, encoding="utf-8")


def write_output_folder(out: Path, command: str, files: dict[str, str | bytes], inputs: Iterable[Path] = ()) -> Path:
    """Write `files` ({relative path: text or bytes}) as the output of `command` into `out`, with the
    rules of `fusionkit run --out` (atomic_directory): all or nothing, never over a user's file, never
    into a folder holding an input. Returns the folder; errors are one-line FusionkitErrors."""
    try:
        with atomic_directory(out, command, inputs) as tmp:
            write_files(tmp, files, f"fusionkit {command}")
    except OSError as exc:
        raise write_error(out, exc) from None
    return Path(out)
