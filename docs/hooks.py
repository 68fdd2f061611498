"""mkdocs hooks of the documentation site (``hooks:`` in mkdocs.yml).

The docstrings name other objects with Sphinx's roles (``:class:`~emasim.sim.result.Result```),
which mkdocstrings renders as the role's text before a code span. :func:`plain_roles` drops
the role and, for a ``~`` reference, keeps the last part of the name, as Sphinx shows it; a
role still there after it is a warning, so ``mkdocs build --strict`` fails on it.
"""

import logging
import re

ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|attr|data|obj|exc):<code>(~?)([^<]*)</code>")
LEFTOVER = re.compile(r":(?:class|func|meth|mod|attr|data|obj|exc):`")
log = logging.getLogger("mkdocs.plugins.emasim")


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
