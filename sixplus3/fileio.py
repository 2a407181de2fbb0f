"""Reading user files safely: size cap, UTF-8, bounded YAML aliases, no duplicate keys.

Every YAML a user hands to sixplus3 (tasks, robots, closures) goes through
:func:`read_yaml`.  What it refuses, each with an :class:`~sixplus3.errors.InputError`
naming the file and the valid range:

- files larger than ``max_bytes`` (default 1 MiB);
- bytes that are not UTF-8 (e.g. a Latin-1 file);
- more than ``max_aliases`` YAML aliases, or aliases that expand the document to more
  than ``max_values`` values (a "billion laughs" bomb is a few hundred bytes);
- a mapping with the same key twice (YAML says it is an error; PyYAML keeps the last);
- anything but plain data (PyYAML's safe loader: no Python objects).

Atomic writes of one file live here too (:func:`atomic_write`).
"""

from __future__ import annotations

import contextlib
import errno
import io
import json
import math
import os
import re
import stat
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml

from sixplus3.errors import InputError

MAX_BYTES = 1 << 20
MAX_ALIASES = 100
#: Largest number of values a document may expand to (aliases counted as copies).
MAX_VALUES = 100_000


class _Loader(yaml.SafeLoader):
    """SafeLoader that counts aliases and refuses duplicate mapping keys."""

    max_aliases = MAX_ALIASES

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._aliases = 0

    def compose_node(self, parent, index):  # type: ignore[no-untyped-def]
        if self.check_event(yaml.AliasEvent):
            self._aliases += 1
            if self._aliases > self.max_aliases:
                event = self.peek_event()
                raise yaml.YAMLError(f"more than {self.max_aliases} aliases (line "
                                     f"{event.start_mark.line + 1}); expand them by hand")
        return super().compose_node(parent, index)

    def construct_mapping(self, node, deep=False):  # type: ignore[no-untyped-def]
        seen = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            try:
                hash(key)
            except TypeError:
                raise yaml.YAMLError(f"unhashable mapping key at line "
                                     f"{key_node.start_mark.line + 1}") from None
            if key in seen:
                raise yaml.YAMLError(f"duplicate key {key!r} at line "
                                     f"{key_node.start_mark.line + 1}")
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG,
                        _Loader.construct_mapping)
# YAML 1.2 floats: PyYAML (YAML 1.1) reads 1.0e5 or 1e5 as text (it wants 1.0e+5); here
# they are numbers, as in YAML 1.2 and JSON.  Integers keep their own resolver (first).
_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."))

#: Deepest nesting of a user's YAML document.
MAX_DEPTH = 32


def read_bytes(path: str | Path, what: str, max_bytes: int = MAX_BYTES) -> bytes:
    """The bytes of a user file of at most ``max_bytes``; raises InputError."""
    if not isinstance(path, (str, os.PathLike)) or "\x00" in os.fspath(path):
        raise InputError(f"the {what} path must be text without NUL bytes, got "
                         f"{short_repr(path, 60)}", value=short_repr(path, 60),
                         valid="a file path")
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            raw = fh.read(max_bytes + 1)
    except (OSError, ValueError) as exc:
        why = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise InputError(f"cannot read {what} {path}: {why}"[:300],
                         value=str(path)[:200], valid="a readable file") from None
    if len(raw) > max_bytes:
        raise InputError(f"{what} {path} is larger than {max_bytes} bytes", value=len(raw),
                         valid=f"<= {max_bytes} bytes")
    return raw


def read_text(path: str | Path, what: str, max_bytes: int = MAX_BYTES) -> str:
    """The UTF-8 text of a user file of at most ``max_bytes``; raises InputError."""
    raw = read_bytes(path, what, max_bytes)
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"{what} {path} is not UTF-8 text (byte {exc.start}: "
                         f"{raw[exc.start:exc.start + 1]!r}); save it as UTF-8",
                         valid="UTF-8 text", value=exc.start) from exc


def depth(obj: Any, limit: int) -> int:
    """Nesting depth of plain data (dicts and lists), counted up to ``limit + 1``
    without recursion."""
    stack = [(obj, 1)]
    deepest = 0
    while stack:
        o, d = stack.pop()
        deepest = max(deepest, d)
        if deepest > limit:
            return deepest
        if isinstance(o, dict):
            stack.extend((v, d + 1) for v in list(o.keys()) + list(o.values()))
        elif isinstance(o, list):
            stack.extend((v, d + 1) for v in o)
    return deepest


def _nesting(text: str) -> int:
    """A quick upper bound on the flow nesting ([ and {) of YAML text, before the parser
    (which recurses once per level) sees it; block nesting is bounded by indentation."""
    depth = deepest = 0
    for ch in text:
        if ch in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif ch in "]}":
            depth = max(0, depth - 1)
    return deepest


def _node_size(node: yaml.Node, memo: dict[int, tuple[int, int]],
               limit: int) -> tuple[int, int]:
    """(values, depth) of a composed YAML node with its aliases expanded, on the shared
    node graph in linear time (each node once); counting stops past ``limit``."""
    key = id(node)
    if key in memo:
        return memo[key]
    memo[key] = (limit + 1, 0)  # a node inside itself (a recursive alias): too big
    n, d = 1, 0
    children: list[yaml.Node] = []
    if isinstance(node, yaml.MappingNode):
        children = [c for pair in node.value for c in pair]
    elif isinstance(node, yaml.SequenceNode):
        children = list(node.value)
    for child in children:
        cn, cd = _node_size(child, memo, limit)
        n, d = n + cn, max(d, cd)
        if n > limit:
            break
    memo[key] = (n, d + 1)
    return memo[key]


#: What YAML's reader refuses: C0 controls but tab, LF and CR; DEL; C1 controls but NEL;
#: the surrogates and the two non-characters (YAML 1.1, 5.1 "Character Set").
_CONTROL = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\x7f-\x84\x86-\x9f\ud800-\udfff"
                      "\ufffe\uffff]")


def parse_yaml(text: str, what: str, max_aliases: int = MAX_ALIASES,
               max_values: int = MAX_VALUES) -> Any:
    """Plain data from YAML text with bounded aliases, bounded expanded size and depth
    (both counted on the composed node graph, before any value is built) and unique
    keys."""
    if _nesting(text) > MAX_DEPTH:
        raise InputError(f"{what} nests deeper than {MAX_DEPTH} levels", value=">" +
                         str(MAX_DEPTH), valid=f"<= {MAX_DEPTH} levels")
    bad = _CONTROL.search(text)
    if bad is not None:
        line = text.count("\n", 0, bad.start()) + 1
        raise InputError(f"{what} holds the control character {ord(bad.group()):#04x} at "
                         f"line {line} (a YAML file holds printable text, tabs and "
                         "newlines only)", value=f"{ord(bad.group()):#04x}",
                         valid="printable characters, tab, newline")
    try:
        loader = _Loader(text)
    except yaml.YAMLError as exc:  # the reader refuses what it cannot read
        raise InputError(f"{what} is not valid YAML: {str(exc).splitlines()[0][:200]}",
                         valid="YAML", value=None) from None
    loader.max_aliases = max_aliases
    try:
        node = loader.get_single_node()
        if node is not None:
            # without aliases the file's size cap bounds what it expands to: a long
            # list written out (a hand's path) is no alias bomb, and its depth is
            # measured whole
            size, deep = _node_size(node, {}, max_values if loader._aliases else MAX_BYTES)
            if size > max_values and loader._aliases > 0:
                raise InputError(f"{what}: its aliases expand to more than {max_values} "
                                 "values (a YAML alias bomb?); write the values out",
                                 valid=f"<= {max_values} values", value=max_values + 1)
            if deep > MAX_DEPTH:
                raise InputError(f"{what} nests deeper than {MAX_DEPTH} levels",
                                 value=">" + str(MAX_DEPTH), valid=f"<= {MAX_DEPTH} levels")
        doc = None if node is None else loader.construct_document(node)
    except yaml.YAMLError as exc:
        first = str(exc).strip().splitlines()
        msg = " ".join(line.strip() for line in first[:3])[:300]
        raise InputError(f"{what} is not valid YAML: {msg}", valid="YAML", value=msg) from None
    except RecursionError:
        raise InputError(f"{what} nests too deep", value=None,
                         valid=f"<= {MAX_DEPTH} levels") from None
    finally:
        loader.dispose()
    return doc


def read_yaml(path: str | Path, what: str = "file", max_bytes: int = MAX_BYTES,
              max_aliases: int = MAX_ALIASES) -> Any:
    """Plain data from a YAML (or JSON) user file; raises InputError."""
    text = read_text(path, what, max_bytes)  # checks that path is a path
    return parse_yaml(text, f"{what} {Path(path)}", max_aliases)


def short_repr(value: object, limit: int = 80) -> str:
    """repr cut to ``limit`` characters (error messages never echo a whole document)."""
    r = repr(value)
    return r if len(r) <= limit else r[:limit - 3] + "..."


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


#: The process's umask, read once at import: files are created 0o666 & ~umask, as
#: ``open`` would (``mkstemp`` alone makes them 0o600).
UMASK = _umask()


def _check_target(path: Path) -> None:
    """Only a regular file, a link (replaced itself, never followed) or nothing may be at
    ``path``, in an existing directory."""

    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        mode = None
    if mode is not None and not (stat.S_ISREG(mode) or stat.S_ISLNK(mode)):
        raise IsADirectoryError(errno.EISDIR if stat.S_ISDIR(mode) else errno.EINVAL,
                                "not a regular file, not replaced", str(path))
    if not path.parent.is_dir():
        raise FileNotFoundError(errno.ENOENT, "no such directory for the output",
                                str(path))


def _fsync_dir(directory: Path) -> None:
    dfd = os.open(directory, os.O_RDONLY | os.O_DIRECTORY)
    try:
        os.fsync(dfd)
    finally:
        os.close(dfd)


def first_non_finite(doc: object, where: str = "") -> str | None:
    """Path of the first NaN or infinite number in a loaded document, or None."""
    if isinstance(doc, float) and not math.isfinite(doc):
        return where or "(top level)"
    if isinstance(doc, dict):
        for k, v in doc.items():
            hit = first_non_finite(v, f"{where}.{k}" if where else str(k))
            if hit:
                return hit
    if isinstance(doc, list):
        for i, v in enumerate(doc):
            hit = first_non_finite(v, f"{where}[{i}]")
            if hit:
                return hit
    return None


def finite_or_none(obj: Any) -> Any:
    """``obj`` with every NaN or infinite float (numpy's too) replaced by ``None``: JSON
    has no NaN, and strict parsers (JavaScript's ``JSON.parse``) refuse the bare ``NaN``
    that Python's json writes.  Say beside the ``null`` why there is no number."""
    if isinstance(obj, dict):
        return {k: finite_or_none(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [finite_or_none(v) for v in obj]
    if hasattr(obj, "tolist") and hasattr(obj, "dtype"):  # numpy array or scalar
        return finite_or_none(obj.tolist())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def strict_json(obj: Any, indent: int | None = None) -> str:
    """``obj`` as strict JSON (RFC 8259): non-finite numbers as ``null``
    (:func:`finite_or_none`), numpy values as lists and numbers."""

    return json.dumps(finite_or_none(obj), indent=indent, allow_nan=False)


def atomic_write(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` so that an interruption leaves no partial file: a
    temporary file in the same directory, flushed and fsynced, renamed over ``path``,
    then the directory fsynced.  On any error the old file is untouched and the
    temporary file removed; the OSError propagates, naming ``path``.

    Nothing is written through a link: the temporary file has a random name and is
    created with ``O_CREAT | O_EXCL`` (``mkstemp``: a file or link planted under any
    name is never opened), and the rename replaces a link at ``path`` itself, never its
    target.  Only a regular file, a link or nothing at ``path`` is replaced: a device, a
    directory or a FIFO is refused."""
    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            fh.write(data)

    atomic_write_with(path, write)


def save_figure(fig: Any, path: str | Path, dpi: int = 100, tight: bool = False) -> str:
    """Write the matplotlib figure ``fig`` as a PNG at ``path`` atomically
    (:func:`atomic_write_with`) and close it, also when writing fails; returns the path.
    ``tight``: crop to the drawn content (``bbox_inches="tight"``).  The one place a
    figure is saved (design, plots, identification, the wrench)."""
    import matplotlib.pyplot as plt  # deferred: matplotlib loads in ~0.3 s

    extra = {"bbox_inches": "tight"} if tight else {}
    try:
        atomic_write_with(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format="png", **extra))
    finally:
        plt.close(fig)
    return str(path)


def figure_png(fig: Any, dpi: int = 100) -> bytes:
    """The matplotlib figure ``fig`` as PNG bytes (a page that embeds its plots), the
    figure closed, also when drawing fails."""
    import matplotlib.pyplot as plt  # deferred: matplotlib loads in ~0.3 s

    buf = io.BytesIO()
    try:
        fig.savefig(buf, dpi=dpi, format="png", bbox_inches="tight")
    finally:
        plt.close(fig)
    return buf.getvalue()


def atomic_write_with(path: str | Path, write: Callable[[Path], object]) -> None:
    """:func:`atomic_write` for writers that need a file name (``write(tmp)`` fills the
    fresh, empty temporary file ``tmp``, e.g. matplotlib's or xarray's savers)."""
    path = Path(path)
    _check_target(path)
    fd, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name[:80]}.", suffix=".tmp")
    try:
        os.fchmod(fd, 0o666 & ~UMASK)
    finally:
        os.close(fd)
    tmp = Path(name)
    try:
        write(tmp)
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
        _fsync_dir(path.parent)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
