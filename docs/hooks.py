"""mkdocs hooks of the documentation site (``hooks:`` in mkdocs.yml).

A page's line ``<!-- example: NAME.py -->`` becomes the code of ``examples/NAME.py`` as it is
when the site is built (:func:`example_code`), so the examples gallery cannot drift from the
scripts the tests run; ``mkdocs serve`` rebuilds when an example changes.

The docstrings name other objects with Sphinx's roles (``:class:`~emasim.sim.result.Result```),
which mkdocstrings renders as the role's text before a code span. :func:`plain_roles` drops
the role and, for a ``~`` reference, keeps the last part of the name, as Sphinx shows it; a
role still there after it is a warning, so ``mkdocs build --strict`` fails on it.
"""

import logging
import re
from pathlib import Path

ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|attr|data|obj|exc):<code>(~?)([^<]*)</code>")
LEFTOVER = re.compile(r":(?:class|func|meth|mod|attr|data|obj|exc):`")
log = logging.getLogger("mkdocs.plugins.emasim")
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
EXAMPLE = re.compile(r"^<!-- example: ([\w-]+\.py) -->$", re.MULTILINE)


def example_code(markdown: str, where: str) -> str:
    """Each ``<!-- example: NAME.py -->`` line replaced by a fenced python block of
    ``examples/NAME.py``; a warning for a name not in examples/."""

    def code(match: re.Match) -> str:
        path = EXAMPLES / match.group(1)
        if not path.is_file():
            log.warning(f"{where}: no example {match.group(1)} in examples/")
            return match.group(0)
        text = path.read_text().rstrip()
        fence = "`" * max(3, 1 + max(map(len, re.findall("`+", text)), default=0))
        return f"{fence}python\n{text}\n{fence}"

    return EXAMPLE.sub(code, markdown)


def on_page_markdown(markdown: str, page, **kwargs) -> str:
    """Each page's Markdown with the examples' code put in."""
    return example_code(markdown, page.file.src_path)


def on_serve(server, **kwargs):
    """``mkdocs serve`` watches examples/ too."""
    server.watch(str(EXAMPLES))
    return server


def plain_roles(html: str) -> str:
    """``:class:<code>~a.b.C</code>`` -> ``<code>C</code>``; without ``~`` the whole name."""
    return ROLE.sub(
        lambda m: f"<code>{m.group(2).rsplit('.', 1)[-1] if m.group(1) else m.group(2)}</code>",
        html,
    )


def on_page_content(html: str, page, **kwargs) -> str:
    """Each page's HTML with the roles made plain; a warning for any left."""
    html = plain_roles(html)
    if LEFTOVER.search(html) or ROLE.search(html):
        log.warning(f"{page.file.src_path}: a Sphinx role is left in the rendered text")
    return html
