"""Scene files: TOML out, the built-in scenes, reading files and :func:`~roughvib.scene.load_scene`.

The built-in scenes are the ``*.toml`` files of the ``roughvib.scenes`` data package, read with
``importlib.resources`` (so they resolve from an installed wheel too).
"""

from __future__ import annotations

import math
import os
import stat
import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

from roughvib.scene.checks import SceneError
from roughvib.scene.core import _SECTIONS, Scene, scene_from_dict, scene_to_dict

# --------------------------------------------------------------------------------------------
# TOML
# --------------------------------------------------------------------------------------------


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ("inf" if v > 0 else "-inf")
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):  # an inline table
        return "{" + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def scene_to_toml(scene: Scene, *, comments: dict[str, str] | None = None) -> str:
    """Serialise a scene to TOML text that :func:`~roughvib.scene.load_scene` reads back to an
    equal scene.

    Parameters
    ----------
    scene : Scene
    comments : dict, optional
        ``{"excitation.force_amplitude": "calibrated ..."}``: a comment after that key.
    """
    comments = comments or {}
    d = scene_to_dict(scene)
    lines = [f"name = {_toml_value(d['name'])}",
             f"description = {_toml_value(d['description'])}"]
    for sec in _SECTIONS:
        lines.append("")
        lines.append(f"[{sec}]")
        tables = {k: v for k, v in d[sec].items() if isinstance(v, dict)}
        for k, v in d[sec].items():
            if k not in tables:
                c = comments.get(f"{sec}.{k}")
                lines.append(f"{k} = {_toml_value(v)}" + (f"  # {c}" if c else ""))
        for name, table in tables.items():  # [friction.parameters], after the section's keys
            lines.append("")
            lines.append(f"[{sec}.{name}]")
            for k, v in table.items():
                c = comments.get(f"{sec}.{name}.{k}")
                lines.append(f"{k} = {_toml_value(v)}" + (f"  # {c}" if c else ""))
    return "\n".join(lines) + "\n"


def builtin_scenes() -> dict[str, str]:
    """Names of the built-in scenes and their one-line descriptions."""
    out = {}
    for entry in sorted(resources.files("roughvib.scenes").iterdir(), key=lambda e: e.name):
        if entry.name.endswith(".toml"):
            data = tomllib.loads(entry.read_text())
            out[entry.name[:-5]] = data.get("description", "")
    return out


_FILE_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a named pipe (FIFO)"),
               (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
               (stat.S_ISSOCK, "a socket"))


def read_regular_file(path: Path, what: str) -> bytes:
    """The bytes of a regular file, refusing anything else in one line before reading.

    The file is opened without blocking and checked on the open descriptor, so a named pipe
    is refused at once instead of waiting for a writer, and nothing can swap the file between
    the check and the read.

    Parameters
    ----------
    path : Path
    what : str
        What the file is, for the message (``"scene file"``, ``"sweep file"``).

    Raises
    ------
    SceneError
        Unreadable, or not a regular file: ``<what> <path> must be a regular file, got a named
        pipe (FIFO)``.
    """
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as exc:
        raise SceneError(f"{what} {path} cannot be read: {exc.strerror}") from None
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            kind = next((k for test, k in _FILE_KINDS if test(mode)), "not a file")
            raise SceneError(f"{what} {path} must be a regular file, got {kind}")
        chunks = []
        while chunk := os.read(fd, 1 << 20):
            chunks.append(chunk)
        return b"".join(chunks)
    except OSError as exc:
        raise SceneError(f"{what} {path} cannot be read: {exc.strerror}") from None
    finally:
        os.close(fd)


def read_toml_file(path: Path, what: str = "scene file") -> dict[str, Any]:
    """Read a TOML file as UTF-8 (a leading byte-order mark is accepted and dropped).

    Parameters
    ----------
    path : Path
    what : str
        What the file is, for the message (``"scene file"``, ``"sweep file"``).

    Raises
    ------
    SceneError
        Unreadable file, not a regular file (a directory, a named pipe, a device: reading a
        pipe would wait for a writer forever), bytes that are not UTF-8 (the line and the byte
        are named), or invalid TOML; one line.
    """
    raw = read_regular_file(path, what)
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise SceneError(f"{what} {path} must be UTF-8 text (save it as UTF-8), got byte "
                         f"0x{raw[exc.start]:02x} on line {line}") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{what} {path} is not valid TOML: {exc}") from None


def load_scene(source: str | Path | None = "paper", overrides: dict[str, Any] | None = None,
               **kw: Any) -> Scene:
    """Load a built-in scene by name or a TOML scene file, then apply overrides.

    Parameters
    ----------
    source : str or Path, optional
        A built-in name (``"paper"``, ``"paper-100mms"``, ...; see :func:`builtin_scenes`) or a
        path to a ``.toml`` file. An empty file is the paper scene.
    overrides : dict, optional
        Dotted keys, e.g. ``{"block.mass": 0.543, "output.duration": 0.2}``.
    **kw
        More overrides: ``load_scene("paper", **{"block.mass": 0.543})`` or
        ``load_scene("paper", block__mass=0.543)``.

    Returns
    -------
    Scene

    Raises
    ------
    SceneError
        Unknown scene, unreadable file, unknown key or invalid value.

    Examples
    --------
    >>> scene = load_scene("paper", **{"output.duration": 0.05})
    >>> scene.block.mass
    0.221
    """
    if source is None:
        source = "paper"
    builtins = builtin_scenes()
    if isinstance(source, str) and source in builtins:
        text = resources.files("roughvib.scenes").joinpath(f"{source}.toml").read_text()
        data = tomllib.loads(text)
        base = Path.cwd()
    else:
        path = Path(source)
        if not path.exists():
            raise SceneError(f"scene {str(source)!r} is neither a built-in scene "
                             f"({', '.join(builtins)}) nor an existing file")
        data = read_toml_file(path)
        base = path.resolve().parent
    scene = scene_from_dict(data, base_dir=base)
    if overrides or kw:
        scene = scene.with_overrides(overrides, **kw)
    return scene
