"""Generated blocks of a page (the README, a docs page): the lines between
``<!-- NAME:begin -->`` and ``<!-- NAME:end -->``, which a script writes from what it measured
and a test compares with what the stored numbers render. Every such block follows one rule: its
body is the text between the two marker lines, less the newline that ends the line before the
end marker (a body that ends with a newline leaves an empty line there).
"""

from pathlib import Path


def markers(name: str) -> tuple[str, str]:
    """The begin and end lines of the block ``name``."""
    return f"<!-- {name}:begin -->", f"<!-- {name}:end -->"


def _span(text: str, name: str) -> tuple[int, int]:
    begin, end = markers(name)
    start = text.index(begin + "\n") + len(begin) + 1
    return start, text.index("\n" + end, start - 1)


def block_of(text: str, name: str) -> str:
    """The body of the block ``name`` in ``text`` (ValueError where it has none)."""
    start, stop = _span(text, name)
    return text[start:stop]


def with_block(text: str, name: str, body: str) -> str:
    """``text`` with the body of its block ``name`` replaced by ``body``."""
    start, stop = _span(text, name)
    return text[:start] + body + text[stop:]


def write_block(page: Path, name: str, body: str) -> None:
    """Rewrite the block ``name`` of the file ``page`` with ``body``."""
    page.write_text(with_block(page.read_text(), name, body))
