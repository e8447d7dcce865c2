"""What an output path may replace (issue 23): the one check every command with ``--out`` runs.

A folder that a usv_mj command wrote carries a manifest, ``.usv_mj-manifest.json``: the tool, its
version, the command lines that wrote into it and every relative path they wrote (a file with its
size in bytes and SHA-256, a folder, or, for a sweep that streams its results and must stay
resumable after a kill, a name pattern such as ``logs/run-*.mcap``). ``--overwrite`` replaces only
what such a manifest lists, unchanged:

* :func:`check_folder` (run, compare, sweep, capability, plot): the folder is new, empty, or holds
  usv_mj's outputs and nothing else. A file, folder, hidden file or symbolic link the manifest does
  not list (or a listed file whose bytes changed since) is refused, naming the first one, whatever
  the flags. A folder with no manifest is refused unless it is a run or a sweep of a usv_mj version
  before manifests (``summary.json`` + ``run.mcap``, or ``sweep.json`` + ``results.parquet``,
  and nothing but the names those versions wrote). The root, a mount point, the current folder,
  the home folder and their parents are refused too.
* :func:`check_file` (render, env: a video and its still; scene: an MJCF file): the file is new,
  or its folder's manifest lists it. :func:`write_file` then writes such a file whole or not at
  all (never through a symbolic link, never a cut or empty file on a full disk) and lists it.
* :class:`Staging` writes a job into ``.NAME.staging-PID`` beside ``out`` and moves it into place
  at the end with its manifest; the old folder's listed files are then deleted one by one (never a
  whole tree): anything unlisted that appeared meanwhile stays where it was. A job that failed
  (a crash, an output that could not be written) does not replace an earlier output:
  :meth:`Staging.set_aside` keeps its files in ``.NAME.failed-PID`` beside ``out``, which the next
  job into ``out`` clears.

Every refusal is one :class:`usv_mj.core.errors.ScenarioError` line (exit 2), raised before anything is
made. A name whose staging name would be over 255 bytes is refused the same way.
"""

from __future__ import annotations

import hashlib
import json
import os
import shlex
import sys
import tempfile
from pathlib import Path, PurePosixPath

from usv_mj.core.errors import ScenarioError

MANIFEST = ".usv_mj-manifest.json"
STAGING_MARK = ".usv_mj-staging"     # in a staging folder while its job runs
NAME_MAX = 255                        # bytes in one file name (Linux, macOS)
_PID_MAX = "4194304"                  # the largest pid Linux hands out (pid_max limit)

#: What usv_mj versions before the manifest wrote, by the files that mark each kind of folder.
LEGACY = {("summary.json", "run.mcap"): ("summary.json", "report.md", "run.mcap", "baseline.mcap", "video.mp4",
                                          "video.png", "run.mp4", "run.png", "traceback.txt", "figures",
                                          "figures/*.png"),
          ("sweep.json", "results.parquet"): ("sweep.json", "results.parquet", "report.md", "figures",
                                              "figures/*.png", "logs", "logs/run-*.mcap")}

_command: list[str] | None = None


def set_command(argv: list[str]) -> None:
    """The command line the manifests record (``usv_mj.cli.main.main`` sets it)."""
    global _command
    _command = list(argv)


def command_line() -> str:
    return shlex.join(_command if _command is not None else [Path(sys.argv[0]).name, *sys.argv[1:]])


# --- what a folder holds ------------------------------------------------------------------------


def entries(folder: Path) -> list[str]:
    """Every path under ``folder`` (files, folders, symbolic links, hidden ones too), relative and
    POSIX-style, parents before children; links are not followed."""
    out: list[str] = []

    def walk(d: Path, prefix: str) -> None:
        with os.scandir(d) as it:
            for e in sorted(it, key=lambda e: e.name):
                rel = prefix + e.name
                out.append(rel)
                if e.is_dir(follow_symlinks=False):
                    walk(Path(e.path), rel + "/")
    walk(folder, "")
    return out


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def read_manifest(folder: Path) -> dict | None:
    """The folder's manifest, or None when it has none or it is not one of usv_mj's."""
    path = Path(folder) / MANIFEST
    if path.is_symlink() or not path.is_file():
        return None
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not (isinstance(data, dict) and data.get("tool") == "usv_mj" and isinstance(data.get("files"), dict)
            and isinstance(data.get("dirs", []), list) and isinstance(data.get("patterns", []), list)):
        return None
    return data


def _legacy_manifest(folder: Path) -> dict | None:
    for markers, names in LEGACY.items():
        if all((folder / m).is_file() and not (folder / m).is_symlink() for m in markers):
            return {"tool": "usv_mj", "files": {}, "dirs": [], "patterns": list(names), "legacy": True,
                    "commands": [f"a usv_mj run before manifests ({' + '.join(markers)})"]}
    return None


def _matches(rel: str, pattern: str) -> bool:
    p, q = PurePosixPath(rel), PurePosixPath(pattern)
    return len(p.parts) == len(q.parts) and p.match(pattern)


def _owned(folder: Path, rel: str, manifest: dict) -> str | None:
    """None when ``rel`` is listed in ``manifest`` as it is now; else why it is not usv_mj's."""
    path = folder / rel
    if path.is_symlink():
        return "a symbolic link, which usv_mj never writes"
    if path.is_dir():
        if rel in manifest.get("dirs", []) or any(_matches(rel, p) for p in manifest.get("patterns", [])):
            return None
        return "not in its manifest"
    if any(_matches(rel, p) for p in manifest.get("patterns", [])):
        return None                        # listed by name: a file its command rewrites as it goes
    entry = manifest["files"].get(rel)
    if entry is None:
        return "not in its manifest"
    if not path.is_file():
        return "not a regular file"
    if entry.get("size") is not None and (path.stat().st_size != entry["size"] or _sha256(path) != entry.get("sha256")):
        return "changed since usv_mj wrote it"
    return None


def foreign(folder: Path) -> tuple[str, str] | None:
    """The first path in ``folder`` that no usv_mj command wrote (with why), or None."""
    folder = Path(folder)
    names = [e for e in entries(folder) if e != MANIFEST]
    manifest = read_manifest(folder) or _legacy_manifest(folder)
    if manifest is None:
        return (names[0], f"the folder has no {MANIFEST}") if names else None
    for rel in names:
        why = _owned(folder, rel, manifest)
        if why is not None:
            return rel, why
    return None


def describe(folder: Path) -> str:
    manifest = read_manifest(folder) or _legacy_manifest(folder)
    commands = (manifest or {}).get("commands") or ["usv_mj"]
    return commands[-1]


# --- the manifest ---------------------------------------------------------------------------------


def record(folder: Path, paths=None, *, patterns=(), command: str | None = None, fresh: bool = False) -> None:
    """Add ``paths`` (relative to ``folder``; None: everything in it) and name ``patterns`` to the
    folder's manifest, creating it (``fresh``: a new one); each file with its size and SHA-256,
    its folders listed too."""
    from usv_mj.core.version import __version__

    folder = Path(folder)
    manifest = None if fresh else read_manifest(folder) or _legacy_manifest(folder)
    manifest = manifest or {
        "tool": "usv_mj", "format": 1, "files": {}, "dirs": [], "patterns": [], "commands": []}
    manifest.pop("legacy", None)
    manifest["version"] = __version__
    rels = [e for e in entries(folder) if e != MANIFEST] if paths is None else [str(PurePosixPath(p)) for p in paths]
    dirs = set(manifest.get("dirs", []))
    for rel in rels:
        path = folder / rel
        if path.is_symlink() or not path.exists():
            continue
        parts = PurePosixPath(rel).parts
        dirs.update("/".join(parts[:i]) for i in range(1, len(parts)))
        if path.is_dir():
            dirs.add(rel)
        else:
            manifest["files"][rel] = {"size": path.stat().st_size, "sha256": _sha256(path)}
    manifest["dirs"] = sorted(dirs)
    manifest["patterns"] = sorted(set(manifest.get("patterns", [])) | set(patterns))
    cmd = command or command_line()
    if not manifest["commands"] or manifest["commands"][-1] != cmd:
        manifest["commands"].append(cmd)
    manifest["command"] = manifest["commands"][0]
    tmp = folder / f"{MANIFEST}.{os.getpid()}.tmp"
    try:
        tmp.write_text(json.dumps(manifest, indent=1) + "\n")
        tmp.replace(folder / MANIFEST)
    except OSError as exc:      # a full disk: name the manifest (a file's close() names nothing)
        raise OSError(exc.errno, exc.strerror, str(folder / MANIFEST)) from None
    finally:
        tmp.unlink(missing_ok=True)


def remove_written(folder: Path) -> list[str]:
    """Delete what the folder's manifest lists, as listed (files one by one, then the folders that
    are left empty, then the manifest); returns what stays (nothing usv_mj wrote is kept, nothing
    else is touched)."""
    folder = Path(folder)
    manifest = read_manifest(folder) or _legacy_manifest(folder)
    if manifest is None:
        return [e for e in entries(folder)]
    kept = []
    names = [e for e in entries(folder) if e != MANIFEST]
    for rel in reversed(names):                      # children before parents
        path = folder / rel
        if _owned(folder, rel, manifest) is not None:
            kept.append(rel)
        elif path.is_dir():
            try:
                path.rmdir()
            except OSError:
                kept.append(rel)
        else:
            path.unlink()
    if not kept:
        (folder / MANIFEST).unlink(missing_ok=True)
    return sorted(kept)


# --- the checks -------------------------------------------------------------------------------


def check_names(path: Path, flag: str, *, staged: bool = False) -> None:
    """Every part of ``path`` fits the file system's name limit (255 bytes), and so do the names
    made beside it (``.NAME.staging-PID``, ``.NAME.old-PID``, ``.NAME.lock``; a temporary file)."""
    for part in Path(path).parts:
        if len(os.fsencode(part)) > NAME_MAX:
            raise ScenarioError(f"{flag} {str(path)[:80]}...: the name {part[:40]}... is over {NAME_MAX} bytes")
    name = Path(path).name
    longest = f".{name}.staging-{_PID_MAX}" if staged else f".{name}.{_PID_MAX}.tmp"
    if len(os.fsencode(longest)) > NAME_MAX:
        room = NAME_MAX - (len(os.fsencode(longest)) - len(os.fsencode(name)))
        raise ScenarioError(f"{flag} {str(path)[:80]}...: the name is {len(os.fsencode(name))} bytes; the "
                            f"temporary name made beside it would be over {NAME_MAX}: use at most {room} bytes")


def _home_and_cwd() -> list[tuple[Path, str]]:
    places = []
    for path, what in ((Path.cwd(), "the current folder"), (Path(os.path.expanduser("~")), "the home folder")):
        try:
            places.append((path.resolve(), what))
        except OSError:
            pass
    return places


_NEVER = ("the current folder, the root or a mount point, the home folder or a folder holding one of them "
          "is never an output folder")


def _refused_place(out: Path, flag: str) -> None:
    """The root, a mount point, the current folder, the home folder and their parents: never an
    output folder (replacing one whole is never what was meant, and most cannot be renamed)."""
    resolved = out.resolve()
    if resolved == Path(resolved.anchor):
        raise ScenarioError(f"{flag} {out}: is the root folder ({_NEVER}); name a new folder inside it")
    if os.path.ismount(resolved):
        raise ScenarioError(f"{flag} {out}: is a mount point ({_NEVER}); name a new folder inside it")
    for place, what in _home_and_cwd():
        if resolved == place or resolved in place.parents:
            rel = "is" if resolved == place else "holds"
            raise ScenarioError(f"{flag} {out}: {rel} {what} ({_NEVER}); name a new folder inside it")


def _existing_ancestor(out: Path, flag: str) -> Path:
    ancestor = out
    while not ancestor.exists():
        if ancestor.is_symlink():
            raise ScenarioError(f"{flag} {out}: {ancestor} is a broken symbolic link")
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise ScenarioError(f"{flag} {out}: {ancestor} is a file, so nothing can be made under it")
    return ancestor


def _probe(ancestor: Path, out: Path, flag: str) -> None:
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".usv-mj-probe-", dir=ancestor))
    except OSError as exc:
        raise ScenarioError(f"{flag} {out}: cannot write in {ancestor} ({exc.strerror or exc})") from None


def _refuse_foreign(folder: Path, out: Path, flag: str) -> None:
    found = foreign(folder)
    if found is not None:
        rel, why = found
        raise ScenarioError(f"{flag} {out}: holds {rel}, which no usv_mj command wrote ({why}); nothing was "
                            "changed: choose a new or empty folder, or move it away")


def check_folder(out, overwrite: bool = False, flag: str = "--out", *, resume: bool = False,
                 writes: tuple[str, ...] | None = None) -> Path:
    """``out`` can take a command's outputs. ``writes`` None: the command replaces the folder whole
    (run, compare, sweep, capability); a tuple of relative paths: it writes those inside (plot).
    An existing usv_mj folder needs ``overwrite`` (or ``resume``: a sweep continues in it)."""
    if str(out) == "":
        raise ScenarioError(f"{flag} '': an empty path; name the output folder")
    out = Path(out)
    check_names(out, flag, staged=writes is None)
    if out.is_symlink():
        raise ScenarioError(f"{flag} {out}: is a symbolic link; name the folder itself")
    if out.exists() and not out.is_dir():
        raise ScenarioError(f"{flag} {out}: is a file, not a folder")
    if writes is None or not out.exists():
        _refused_place(out, flag)
    ancestor = _existing_ancestor(out, flag)
    if out.is_dir():
        _refuse_foreign(out, out, flag)
        if writes is None and any(e != MANIFEST for e in entries(out)) and not (overwrite or resume):
            raise ScenarioError(f"{flag} {out}: already holds a run of usv_mj ({describe(out)}); pass --overwrite "
                                "to replace it whole, or choose another folder")
        present = [w for w in (writes or ()) if (out / w).exists()]
        if present and not overwrite:
            raise ScenarioError(f"{flag} {out}: already holds {', '.join(present)}; pass --overwrite to replace "
                                "them, or choose another folder")
        ancestor = out if writes is not None else out.parent
    _probe(ancestor, out, flag)
    return out


def check_file(out, overwrite: bool = False, flag: str = "--out", *, suffix: str = ".mp4",
               companions: tuple[str, ...] = (".png",)) -> Path:
    """``out`` (and the files beside it with the ``companions`` suffixes) can be written: new, or
    listed unchanged in its folder's manifest and ``overwrite`` given."""
    if str(out) == "":
        raise ScenarioError(f"{flag} '': an empty path; name the output file")
    out = Path(out)
    check_names(out, flag)
    if out.suffix.lower() != suffix:
        if out.is_dir():
            raise ScenarioError(f"{flag} {out}: is a folder; name the file (e.g. {out / ('video' + suffix)})")
        raise ScenarioError(f"{flag} {out}: the file's name ends in {suffix}")
    ancestor = _existing_ancestor(out.parent, flag)
    existing = [p for p in (out, *(out.with_suffix(s) for s in companions)) if p.exists() or p.is_symlink()]
    for p in existing:
        if p.is_dir() and not p.is_symlink():
            raise ScenarioError(f"{flag} {out}: {p} is a folder")
        manifest = read_manifest(p.parent) or _legacy_manifest(p.parent)
        why = f"its folder has no {MANIFEST}" if manifest is None else _owned(p.parent, p.name, manifest)
        if why is not None:
            raise ScenarioError(f"{flag} {out}: {p} exists and no usv_mj command wrote it ({why}); nothing was "
                                "changed: name another file")
    if existing and not overwrite:
        raise ScenarioError(f"{flag} {out}: {existing[0]} exists; pass --overwrite to replace it, or name another file")
    _probe(ancestor, out, flag)
    return out


def record_file(out, companions: tuple[str, ...] = (".png",)) -> None:
    """After :func:`check_file`'s output was written: list it (and its companions) in its folder's manifest."""
    out = Path(out)
    record(out.parent, [p.name for p in (out, *(out.with_suffix(s) for s in companions)) if p.is_file()])


def write_file(out, data: str | bytes) -> None:
    """Write ``data`` to ``out`` (checked by :func:`check_file`) whole or not at all: into a new
    temporary file beside it, renamed over it once complete (a full disk or a read-only folder
    raises OSError naming ``out`` and leaves ``out`` as it was; a symbolic link named ``out`` is
    replaced, never written through), then listed in its folder's manifest (:func:`record_file`)."""
    out = Path(out)
    raw = data.encode() if isinstance(data, str) else bytes(data)
    tmp = out.parent / f".{out.name}.{os.getpid()}.tmp"     # the name check_names allows for
    if os.path.lexists(tmp):                                 # left by a dead process of this pid
        os.unlink(tmp)
    try:
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)   # the umask applies
            with os.fdopen(fd, "wb") as fh:
                fh.write(raw)
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, out)
        except OSError as exc:
            raise OSError(exc.errno, exc.strerror, str(out)) from None
    finally:
        if os.path.lexists(tmp):
            os.unlink(tmp)
    record_file(out, companions=())


# --- staging -------------------------------------------------------------------------------------


class Staging:
    """A job writes into ``.<name>.staging-<pid>`` beside ``out``; :meth:`commit` writes the
    manifest of what is in it and moves it into place (an earlier usv_mj folder there, which
    :func:`check_folder` let through, goes: its listed files, one by one). Staging folders and old
    folders of killed jobs (their process is gone) are cleared first, the same way."""

    def __init__(self, out: Path):
        self.out = Path(out)
        #: ``out`` holds an earlier output (check_folder let it through): a failed job keeps it
        self.replaces = self.out.is_dir() and any(True for _ in os.scandir(self.out))
        parent = self.out.parent
        self._made = [p for p in [parent, *parent.parents] if not p.exists()]   # removed again if nothing comes
        parent.mkdir(parents=True, exist_ok=True)
        self._cleanup_killed(parent, self.out.name)
        self.path = parent / f".{self.out.name}.staging-{os.getpid()}"
        if self.path.exists() and (self.path / STAGING_MARK).exists():
            import shutil

            shutil.rmtree(self.path)
        self.path.mkdir()
        (self.path / STAGING_MARK).touch()

    @staticmethod
    def _cleanup_killed(parent: Path, name: str) -> None:
        import shutil

        for p in parent.glob(f".{name}.failed-*"):      # a failed job's outputs, kept until this job
            if (p / STAGING_MARK).exists():
                shutil.rmtree(p, ignore_errors=True)
        for p in list(parent.glob(f".{name}.staging-*")) + list(parent.glob(f".{name}.old-*")):
            try:
                os.kill(int(p.name.rsplit("-", 1)[1]), 0)
                continue                          # a job still running
            except (ValueError, ProcessLookupError):
                pass
            except PermissionError:
                continue
            if p.name.startswith(f".{name}.old-"):
                if not (parent / name).exists():
                    p.rename(parent / name)       # killed between the two renames of a commit
                elif not remove_written(p):
                    p.rmdir()
            elif (p / STAGING_MARK).exists():      # a staging folder is the job's alone
                shutil.rmtree(p, ignore_errors=True)

    def discard(self) -> None:
        """Nothing of the job goes into place (bad input found late): the staging folder and the
        parent folders it made go."""
        import shutil

        if (self.path / STAGING_MARK).exists():
            shutil.rmtree(self.path, ignore_errors=True)
        self._unmake()

    def _unmake(self) -> None:
        for p in self._made:
            try:
                p.rmdir()
            except OSError:
                break

    def _tidy(self) -> None:
        """Drop the temporary files of the job (partial renders, ``*.tmp``)."""
        import shutil

        for tmp in list(self.path.rglob("*.tmp")) + list(self.path.rglob("*.segments.txt")):
            tmp.unlink(missing_ok=True)
        for tmp in self.path.glob(".render-*"):
            shutil.rmtree(tmp, ignore_errors=True)

    def set_aside(self) -> Path | None:
        """The job failed: ``out`` keeps its earlier output, and what the job wrote goes to
        ``.NAME.failed-PID`` beside it (cleared by the next job into ``out``); that folder, or
        None when the job wrote nothing (the staging folder and the parents it made then go)."""
        import shutil

        if not self.path.exists():
            return None
        self._tidy()
        if not any(p.name != STAGING_MARK for p in self.path.iterdir()):
            self.discard()
            return None
        aside = self.out.parent / f".{self.out.name}.failed-{os.getpid()}"
        if aside.exists() and (aside / STAGING_MARK).exists():
            shutil.rmtree(aside)          # an earlier failed job of this same process
        self.path.rename(aside)           # keeps its mark: the next job's clean-up knows it is usv_mj's
        self.path = aside
        return aside

    def finish(self, failed: bool) -> Path | None:
        """End the job: a job that ``failed`` (a crash, an output that could not be written) while
        ``out`` holds an earlier output is set aside (:meth:`set_aside`: returns where); any other
        is committed (:meth:`commit`: returns None)."""
        aside = self.set_aside() if failed and self.replaces else None
        if aside is None:
            self.commit()
        return aside

    def commit(self) -> None:
        """Drop temporary files, write the manifest, then put the staging folder in place of ``out``
        (nothing written: ``out`` stays as it was)."""
        if not self.path.exists():
            return
        (self.path / STAGING_MARK).unlink(missing_ok=True)
        self._tidy()
        if not any(self.path.iterdir()):
            self.path.rmdir()
            self._unmake()
            return
        try:
            claimed = (read_manifest(self.path) or {}).get("patterns", [])   # a sweep's names stay names
            record(self.path, patterns=claimed, fresh=True)
        except OSError:
            pass                                  # a full disk: the outputs still go into place
        old = None
        if self.out.exists():
            old = self.out.parent / f".{self.out.name}.old-{os.getpid()}"
            self.out.rename(old)
        self.path.rename(self.out)
        if old is not None:
            kept = remove_written(old)
            if kept:
                print(f"usv-mj: kept {old}: it holds {kept[0]}, which no usv_mj command wrote", file=sys.stderr)
            else:
                old.rmdir()


def results_folder(out, resume: bool = False):
    """Where a sweep or a benchmark writes its results, as a context manager yielding the folder.
    A new (or empty) folder, or ``resume``: ``out`` itself, in place (a killed job stays resumable).
    Replacing an earlier output (``--overwrite``): a :class:`Staging` folder, so the old output stays
    until the new one ends; it goes into place when the job ends or is interrupted (its rows so far
    are resumable there), not when bad input is found late (a ScenarioError: nothing goes into
    place) nor when the job fails (another exception: the earlier output stays, the job's files
    go to :meth:`Staging.set_aside`'s folder, named in a note added to the exception)."""
    import contextlib

    @contextlib.contextmanager
    def _folder():
        path = Path(out)
        stage = Staging(path) if (path.is_dir() and not resume and any(entries(path))) else None
        try:
            yield stage.path if stage else path
        except ScenarioError:
            if stage:
                stage.discard()
            raise
        except (KeyboardInterrupt, GeneratorExit):
            raise
        except BaseException as exc:
            if stage:
                staged, stage_ = str(stage.path), stage
                stage = None                       # not committed below
                aside = stage_.set_aside()
                if isinstance(exc, OSError) and aside is not None and str(exc.filename or "").startswith(staged):
                    exc.filename = str(aside) + str(exc.filename)[len(staged):]
                exc.add_note(f"{path} still holds the earlier output; "     # the command line prints it
                             + (f"what this job wrote is in {aside}/ until the next job into it" if aside else
                                "this job wrote nothing"))
            raise
        finally:
            if stage and stage.path.exists():
                stage.commit()

    return _folder()
