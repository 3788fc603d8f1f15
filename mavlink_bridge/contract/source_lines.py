"""Line numbers of the project's YAML input files, for one-line errors a user can act on.

The mission YAML is read by both sides (the simulator its ``world:``, the autopilot its ``mission:`` and
``fence:``), and the autopilot also reads parameter and script files. Every reader reports a problem as
``FILE:LINE: what is wrong; fix: what to write instead`` (the form compilers use, which editors and
terminals turn into links). This module parses a YAML text once into plain Python data plus a map from
each node's path (mapping keys as ``str``, sequence indices as ``int``) to its 1-based line.
"""

from __future__ import annotations

import copy
import difflib
import functools
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

_FAST_LOADER: Any = getattr(yaml, "CSafeLoader", yaml.SafeLoader)  # libyaml's parser, Python's constructor
#: A node's place in a YAML document: ``("mission", 3, "waypoint", "alt_m")``.
NodePath = tuple[str | int, ...]


_SYNTAX_FIX = "check the indentation, the ':' after each key and the '-' before each list entry there or just above"


class YamlSyntaxError(ValueError):
    """A file that is not valid YAML; the message is ``FILE:LINE: not valid YAML: ...; fix: ...``."""

    def __init__(self, path: str | Path, line: int | None, detail: str) -> None:
        where = str(path) if line is None else f"{path}:{line}"
        super().__init__(f"{where}: not valid YAML: {detail}; fix: {_SYNTAX_FIX}")
        self.path = str(path)
        self.line = line
        self.detail = detail
        self.fix = _SYNTAX_FIX


@dataclass(frozen=True)
class YamlSource:
    """A parsed YAML file: its data and the line of every mapping key and sequence entry."""

    path: str
    data: Any
    lines: dict[NodePath, int]

    def line(self, *path: str | int) -> int | None:
        """The line of the deepest node along ``path`` that the file has (None: not even the first one)."""
        for end in range(len(path), 0, -1):
            found = self.lines.get(_key(path[:end]))
            if found is not None:
                return found
        return None

    def where(self, *path: str | int) -> str:
        """``FILE:LINE`` of the deepest node along ``path`` (``FILE`` alone when none is found)."""
        line = self.line(*path)
        return self.path if line is None else f"{self.path}:{line}"


def _key(path: Sequence[str | int]) -> NodePath:
    return tuple(p if isinstance(p, int) else str(p) for p in path)


def parse_yaml(text: str, path: str | Path) -> YamlSource:
    """Parse ``text`` (read from ``path``); :class:`YamlSyntaxError` with the line on a syntax error.

    A text already parsed in this process is not parsed again (a campaign worker reads the same airframe,
    parameter and world texts for every case, and one case's world file is read by several loaders): the data
    is a fresh copy each time, so callers may change it."""
    source = _parsed(text, str(path))
    return YamlSource(source.path, copy.deepcopy(source.data), source.lines)


@functools.lru_cache(maxsize=64)
def _parsed(text: str, path: str) -> YamlSource:
    """One parse of ``text``: its data and lines (libyaml's parser when installed, ~10x faster than Python's)."""
    try:
        root, data = _compose_and_construct(text, _FAST_LOADER)
    except yaml.YAMLError:
        try:  # Python's parser says what is wrong in its own words (and accepts what libyaml alone refused)
            root, data = _compose_and_construct(text, yaml.SafeLoader)
        except yaml.YAMLError as exc:
            raise syntax_error(path, exc) from None
    lines: dict[NodePath, int] = {}
    if root is not None:
        _walk(root, (), lines)
    return YamlSource(path, data, lines)


def _compose_and_construct(text: str, loader_class: Any) -> tuple[yaml.Node | None, Any]:
    """The document's node tree (for the lines) and its data, from one parse."""
    loader = loader_class(text)
    try:
        root = loader.get_single_node()
        return root, (loader.construct_document(root) if root is not None else None)
    finally:
        loader.dispose()


def read_yaml(path: str | Path) -> YamlSource:
    """Read and parse a YAML file (OSError when it cannot be read, :class:`YamlSyntaxError` when invalid)."""
    return parse_yaml(Path(path).read_text(), path)


def syntax_error(path: str | Path, exc: yaml.YAMLError) -> YamlSyntaxError:
    """A parser's error as one line: the file, the line, what the parser expected, and the fix."""
    mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
    problem = " ".join(str(getattr(exc, "problem", None) or exc).split())
    context = getattr(exc, "context", None)
    detail = f"{problem} ({' '.join(str(context).split())})" if context else problem
    return YamlSyntaxError(path, mark.line + 1 if mark is not None else None, detail)


def _walk(node: yaml.Node, path: NodePath, lines: dict[NodePath, int]) -> None:
    if isinstance(node, yaml.MappingNode):
        for key_node, value_node in node.value:
            child = (*path, str(key_node.value))
            lines.setdefault(child, key_node.start_mark.line + 1)
            _walk(value_node, child, lines)
    elif isinstance(node, yaml.SequenceNode):
        for index, item in enumerate(node.value):
            child = (*path, index)
            lines.setdefault(child, item.start_mark.line + 1)
            _walk(item, child, lines)


def did_you_mean(word: object, choices: Iterable[str]) -> str:
    """``"did you mean 'waypoint'?"`` for the closest of ``choices``, else ``"use one of: a, b, c"``."""
    options = list(choices)
    close = difflib.get_close_matches(str(word), options, n=1, cutoff=0.6)
    return f"did you mean '{close[0]}'?" if close else f"use one of: {', '.join(options)}"
