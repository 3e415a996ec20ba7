"""What every reader shares: text lines streamed as byte tokens, numbers parsed with messages that name the
line, and declared counts checked against the file's size before anything is allocated.

Text is never decoded: numbers are parsed from bytes, so bytes that are not UTF-8 only matter where a number
or a keyword is expected, and the message then shows them escaped (``'caf\\xe9'``).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, BinaryIO

from curvefm.errors import CurvefmError, InvalidInput

MAX_LINE_BYTES = 1 << 16
"""Longest line a text reader accepts: a longer one is binary data, and splitting it would cost 40x its size."""


def shown(token: bytes) -> str:
    """A token as a message shows it: bytes that are not UTF-8 escaped, and said to be so."""
    try:
        return f"'{token[:40].decode()}'"
    except UnicodeDecodeError:
        return f"'{token[:40].decode(errors='backslashreplace')}' (bytes that are not UTF-8 text)"


def numbers(tokens: list[bytes], kind: type[float] | type[int] = float) -> list[Any]:
    """``tokens`` as numbers of ``kind`` (float or int); a ValueError naming the first that is not one."""
    try:
        return [kind(t) for t in tokens]
    except ValueError:
        what = "a number" if kind is float else "an integer"
        for t in tokens:
            try:
                kind(t)
            except ValueError:
                raise ValueError(f"expected {what}, found {shown(t)}") from None
        raise


def counted_ids(tokens: list[bytes]) -> list[int]:
    """A count, then that many integer ids (an OFF face line, a PLY face list); what follows is ignored."""
    (count,) = numbers(tokens[:1], int)
    if not 0 <= count <= len(tokens) - 1:
        raise ValueError(f"a face line lists fewer vertex ids than it declares ({count} declared)")
    return numbers(tokens[1 : 1 + count], int)


class TextLines:
    """The lines of a text mesh file that hold something, as lists of byte tokens, ``#`` comments
    removed.

    Iterating yields one token list per line and keeps ``lineno`` for messages; a line longer than
    :data:`MAX_LINE_BYTES` is refused before it is split.
    """

    def __init__(self, f: BinaryIO, path: Path, fmt: str, *, lineno: int = 0):
        self.path, self.fmt, self.lineno = path, fmt, lineno
        self._lines = iter(f)

    def __iter__(self) -> Iterator[list[bytes]]:
        for line in self._lines:
            self.lineno += 1
            if len(line) > MAX_LINE_BYTES:
                raise self.error(f"the line is longer than {MAX_LINE_BYTES} bytes; is this a binary file?")
            tokens = (line.split(b"#", 1)[0] if b"#" in line else line).split()
            if tokens:
                yield tokens

    def error(self, message: str) -> CurvefmError:
        return InvalidInput(f"{self.path.name} is not a valid {self.fmt} file: line {self.lineno}: {message}")

    def reject_rest(self, what: str) -> None:
        """Refuse content after the last element: it would be read for nothing (comments and blanks are fine)."""
        for tokens in self:
            raise self.error(f"unexpected {shown(tokens[0])} after {what}; remove the trailing content")


@contextmanager
def line_errors(lines: TextLines) -> Iterator[None]:
    """Turn a ValueError or OverflowError raised while parsing into a CurvefmError naming the line."""
    try:
        yield
    except OverflowError:
        raise lines.error("a number is too large") from None
    except ValueError as exc:
        raise lines.error(str(exc)) from None


def check_declared_size(path: Path, declared: str, need: int, size: int) -> None:
    """Refuse a header whose counts need more bytes than the file has, before allocating for them."""
    if need > size:
        raise InvalidInput(
            f"{path.name}: the header declares {declared}, which need at least {need} bytes, "
            f"but the file is shorter ({size} bytes); it is truncated or its header is wrong"
        )
