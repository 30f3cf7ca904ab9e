"""Argument helpers shared by the commands: exit statuses, the one-line input error, ``--set``
parsing and SIGTERM handling. Imported by the command modules, never importing them.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

__all__ = ["EXIT_INPUT", "EXIT_INTERRUPT", "EXIT_OK", "EXIT_PIPE", "EXIT_SOLVER", "EXIT_TERM",
           "InputError", "Terminated", "out_path",
           "failed_run_note", "on_sigterm", "parse_sets", "parse_value"]

EXIT_OK = 0
EXIT_SOLVER = 1
EXIT_INPUT = 2
EXIT_INTERRUPT = 130  # 128 + SIGINT: Ctrl-C
EXIT_PIPE = 141  # 128 + SIGPIPE: the reader of stdout went away (``| head``)
EXIT_TERM = 143  # 128 + SIGTERM


class InputError(Exception):
    """Bad command-line input (exit status 2)."""


class Terminated(KeyboardInterrupt):
    """SIGTERM, turned into an exception so that runs stop the way Ctrl-C stops them."""


def on_sigterm(signum, frame):  # pragma: no cover - exercised through a subprocess
    raise Terminated()


def failed_run_note(directory, summary: dict) -> str:
    """The one line on stderr when a command shows a failed run (events, plot, report)."""
    t_end = (summary.get("partial_result") or {}).get("t_end")
    at = f" at t = {t_end:.6g} s" if t_end is not None else ""
    return (f"roughvib: note: {directory} holds a FAILED run ({summary.get('status', '?')}"
            f"{at}): showing what was recorded up to the failure (partial.nc, events.csv); "
            f"summary.json has the message")


def parse_value(text: str) -> Any:
    """A --set value: TOML syntax (numbers, true/false, [a, b], "str"); bare words are strings."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def parse_sets(items: list[str] | None) -> dict[str, Any]:
    """``--set KEY=VALUE`` items as a dict of dotted scene keys (InputError without ``=`` or
    with a line break: TOML would read a second line as a second statement and drop it)."""
    out: dict[str, Any] = {}
    for item in items or []:
        if "=" not in item:
            raise InputError(f"--set expects section.key=value, got {item!r}")
        if "\n" in item or "\r" in item:
            raise InputError(f"--set takes one value on one line, got {item!r} (a line break "
                             f"would start a second statement)")
        key, value = item.split("=", 1)
        out[key.strip()] = parse_value(value.strip())
    return out


def out_path(value: str | None, option: str = "--out") -> Path | None:
    """The path of an ``--out`` option: None if not given, InputError if given empty.

    An empty value would otherwise fall back to the default directory unnoticed.

    Parameters
    ----------
    value : str or None
        The option's value as parsed.
    option : str
        The option's name, for the message.

    Returns
    -------
    Path or None
    """
    if value is None:
        return None
    if not value.strip():
        raise InputError(f"{option} must name a path, got {value!r} (leave {option} out for the "
                         f"default)")
    return Path(value)
