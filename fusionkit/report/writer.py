"""Output folders that never lose a user's file.

`--out DIR` may be written only when DIR is absent, empty, or an earlier fusionkit output: a folder
holding the marker file `.fusionkit-output`, which lists every file fusionkit wrote there (`files`:
relative paths at every depth), the folders it created (`folders`) and the top-level names (`entries`).
DIR may never be, or contain, one of the run's inputs (config, robot descriptions, data, truth).

Everything is written into a temporary folder inside DIR; only when all of it succeeded is it moved
in, file by file: a file the marker lists is replaced when the new output writes it again and
removed when it does not; every other file, at any depth (inside `plots/` too), is left byte for byte.
A folder fusionkit created that the new output no longer uses is removed only if it is then empty.
A file the marker does not list at a path an output needs (or in the way of one) is refused, with
nothing changed. A marker of an older fusionkit lists only top-level `entries`: a listed file is
fusionkit's; in a listed folder only the files the new output writes again are replaced and every
other file stays (nothing says it is fusionkit's). On any error the moves made are undone, and the
temporary folder, and DIR itself if this call created it, are removed.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Iterable, Iterator

from .. import __version__
from ..errors import FusionkitError, PluginError

MARKER = ".fusionkit-output"
TEMP_PREFIX = ".fusionkit-tmp-"


def _error(out: Path, why: str) -> FusionkitError:
    return FusionkitError(f"--out {out}: {why}")


def _read_marker(folder: Path) -> dict | None:
    try:
        data = json.loads((folder / MARKER).read_text(encoding="utf-8"))
        if not isinstance(data, dict) or not isinstance(data["entries"], list):
            return None
        return data
    except (OSError, ValueError, KeyError, TypeError):
        return None


def output_entries(folder: Path) -> set[str] | None:
    """Top-level entries an earlier fusionkit output wrote into `folder`; None when it has no readable marker."""
    data = _read_marker(folder)
    return None if data is None else {str(e) for e in data["entries"]}


def _safe(rel: object) -> str | None:
    """`rel` as a normalized relative POSIX path inside the output folder, or None if it is not one
    (absolute, `..`, empty, the marker, a temporary folder): such a marker line is never acted on."""
    if not isinstance(rel, str) or not rel or "\\" in rel:
        return None
    path = PurePosixPath(rel)
    if path.is_absolute() or any(part in ("", ".", "..") for part in rel.split("/")) \
            or path.parts[0].startswith(TEMP_PREFIX) or rel == MARKER:
        return None
    return path.as_posix()


def _real_dirs_above(folder: Path, rel: str) -> bool:
    """Every folder between `folder` and `folder/rel` is a real folder (no symbolic link, no file)."""
    here = folder
    for part in PurePosixPath(rel).parts[:-1]:
        here = here / part
        if here.is_symlink() or not here.is_dir():
            return False
    return True


def _is_file(path: Path) -> bool:
    """A file or symbolic link (never followed), not a folder."""
    return path.is_symlink() or (path.exists() and not path.is_dir())


def _is_real_dir(path: Path) -> bool:
    return path.is_dir() and not path.is_symlink()


@dataclass
class _Owned:
    """What the marker in a folder says fusionkit wrote there, checked against what is there now."""
    files: set[str] = field(default_factory=set)     # files fusionkit wrote: replaced or removed
    folders: set[str] = field(default_factory=set)   # folders fusionkit created: removed when empty
    legacy: set[str] = field(default_factory=set)    # an old marker's top-level folders: a file in one
                                                     # is replaced only when the new output writes it

    def replaceable(self, rel: str) -> bool:
        return rel in self.files or PurePosixPath(rel).parts[0] in self.legacy


def _owned(folder: Path) -> _Owned:
    data = _read_marker(folder)
    owned = _Owned()
    if data is None:
        return owned
    legacy = not isinstance(data.get("files"), list)
    names = data["entries"] if legacy else data["files"]
    for rel in filter(None, map(_safe, names)):
        if legacy and "/" in rel:
            continue
        path = folder / rel
        if not _real_dirs_above(folder, rel):
            continue  # a folder on the way is now a link or a file: not the place fusionkit wrote
        if _is_file(path):
            owned.files.add(rel)
        elif legacy and _is_real_dir(path):
            owned.legacy.add(rel)
            owned.folders.add(rel)
    if not legacy and isinstance(data.get("folders"), list):
        owned.folders |= {rel for rel in filter(None, map(_safe, data["folders"]))
                          if _real_dirs_above(folder, rel) and _is_real_dir(folder / rel)}
    return owned


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
    if _read_marker(folder) is None:
        raise _error(out, f"the folder exists, is not empty and was not written by fusionkit (it has no "
                          f"{MARKER} file); choose a new or empty folder (nothing was changed)")
    return folder


@contextmanager
def atomic_directory(out: Path, command: str, inputs: Iterable[Path] = ()) -> Iterator[Path]:
    """Yield an empty temporary folder for the outputs of `command` (e.g. "run"); on success its
    files are moved into `out` (replacing and removing only files the earlier output's marker lists)
    and a marker listing them is written; on error nothing in `out` changes and no temporary folder
    remains."""
    folder = check_output_folder(out, inputs)
    created = [p for p in (folder, *folder.parents) if not p.exists()]
    folder.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=TEMP_PREFIX, dir=folder))
    try:
        yield tmp
        _move_in(folder, tmp, command, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        for part in created:  # innermost first: only the folders this call made, now empty again
            try:
                part.rmdir()
            except OSError:
                break
        raise
    shutil.rmtree(tmp, ignore_errors=True)


def _tree(tmp: Path) -> tuple[list[str], list[str]]:
    """The files (links included, never followed) and folders under `tmp`, as relative POSIX paths."""
    files, folders = [], []
    for root, dirnames, filenames in os.walk(tmp):
        base = Path(root).relative_to(tmp)
        for name in dirnames:
            target = (base / name).as_posix()
            (files if (Path(root) / name).is_symlink() else folders).append(target)
        files.extend((base / name).as_posix() for name in filenames)
    return sorted(files), sorted(folders)


def _removable_folder(folder: Path, rel: str, owned: _Owned) -> bool:
    """The folder `rel` holds only files fusionkit wrote (none the new output keeps) and folders it
    created, so it may make way for a new file."""
    if rel not in owned.folders:
        return False
    for child in (folder / rel).iterdir():
        sub = f"{rel}/{child.name}"
        if _is_real_dir(child):
            if not _removable_folder(folder, sub, owned):
                return False
        elif sub not in owned.files:
            return False
    return True


def _clashes(folder: Path, files: list[str], folders: list[str], owned: _Owned) -> list[str]:
    """Paths in `folder` that are not fusionkit's and stand where the new output puts a file or folder."""
    clash = []
    for rel in folders:  # every folder above a new file is one of these
        path = folder / rel
        if _real_dirs_above(folder, rel) and _is_file(path) and rel not in owned.files:
            clash.append(rel)
    for rel in files:
        path = folder / rel
        if not _real_dirs_above(folder, rel):
            continue  # reported for the folder (or link) above it
        if _is_real_dir(path):
            if not _removable_folder(folder, rel, owned):
                clash.append(rel + "/")
        elif _is_file(path) and not owned.replaceable(rel):
            clash.append(rel)
    return sorted(clash)


def _move_in(folder: Path, tmp: Path, command: str, out: Path) -> None:
    """Move the new output in file by file: files the earlier marker lists are moved aside (replaced or
    no longer written), the new ones in, then the marker; any error undoes every step. Only after that
    are the earlier files deleted and the folders fusionkit created that are now unused and empty removed."""
    owned = _owned(folder)
    files, folders = _tree(tmp)
    clash = _clashes(folder, files, folders, owned)
    if clash:
        shown = ", ".join(clash[:5]) + (f" and {len(clash) - 5} more" if len(clash) > 5 else "")
        raise _error(out, f"{shown} in the folder was not written by fusionkit; move it or choose another "
                          "folder (nothing was changed)")
    new_folders = set(folders)
    entries = sorted(p.name for p in tmp.iterdir())
    # every file fusionkit wrote goes aside (replaced, or no longer written), and one an old marker's
    # folder holds that the new output writes again; no other file is ever moved
    aside_files = sorted(owned.files | {rel for rel in files
                                        if _real_dirs_above(folder, rel) and _is_file(folder / rel)})
    aside = Path(tempfile.mkdtemp(prefix=TEMP_PREFIX, dir=folder))
    undo: list[tuple[str, Path, Path | None]] = []
    made: set[str] = set()
    try:
        for rel in aside_files:
            target = aside / "old" / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            os.rename(folder / rel, target)
            undo.append(("rename", folder / rel, target))
        for rel in files:  # a folder of fusionkit's files (all aside now) where a new file goes
            if _is_real_dir(folder / rel):
                for root, _, _ in sorted(os.walk(folder / rel), key=lambda w: -len(w[0])):  # deepest first
                    os.rmdir(root)
                    undo.append(("rmdir", Path(root), None))
        for rel in folders:  # parents first (sorted)
            if not (folder / rel).exists():
                os.mkdir(folder / rel)
                undo.append(("mkdir", folder / rel, None))
                made.add(rel)
        for rel in files:
            os.rename(tmp / rel, folder / rel)
            undo.append(("rename", tmp / rel, folder / rel))
        marker = {"written_by": f"fusionkit {command}", "fusionkit_version": __version__,
                  "entries": entries,
                  "files": files, "folders": sorted(new_folders & (owned.folders | made))}
        (aside / "marker").write_text(json.dumps(marker, indent=1) + "\n", encoding="utf-8")
        if (folder / MARKER).exists():
            os.rename(folder / MARKER, aside / "marker.old")
            undo.append(("rename", folder / MARKER, aside / "marker.old"))
        os.rename(aside / "marker", folder / MARKER)
    except BaseException:
        if _undo(undo):
            shutil.rmtree(aside, ignore_errors=True)
        raise
    shutil.rmtree(aside, ignore_errors=True)
    for rel in sorted(owned.folders - new_folders, key=lambda r: -r.count("/")):  # deepest first
        try:
            os.rmdir(folder / rel)  # only when empty: a user's file inside keeps it
        except OSError:
            pass


def _undo(steps: list[tuple[str, Path, Path | None]]) -> bool:
    """Reverse `steps` (last first); True when all of them were undone."""
    ok = True
    for kind, a, b in reversed(steps):
        try:
            if kind == "rename":
                os.rename(b, a)
            elif kind == "mkdir":
                os.rmdir(a)
            else:
                os.mkdir(a)
        except OSError:
            ok = False
    return ok


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
