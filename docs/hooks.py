"""mkdocs hook: the package's docstrings cross-reference in Sphinx roles (``:class:`~psbmpc_jax.packing.Capacities```);
mkdocstrings renders those as literal text.  Show them as code instead: drop the role and, as Sphinx does for ``~``,
keep only the last dotted part."""

from __future__ import annotations

import re

_ROLE = re.compile(r":(?:class|func|meth|attr|data|mod|obj|exc):\s*<code>(~?)([^<]*)</code>")


def _code(match: re.Match[str]) -> str:
    tilde, target = match.groups()
    return f"<code>{target.rsplit('.', 1)[-1] if tilde else target}</code>"


def on_page_content(html: str, **kwargs: object) -> str:
    return _ROLE.sub(_code, html)
