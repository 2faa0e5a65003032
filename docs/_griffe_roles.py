"""A griffe extension (mkdocs.yml: mkdocstrings' ``extensions``): the docstrings' Sphinx roles
as Markdown code before they are parsed, so that mkdocstrings reads them.

``:class:`~jaxfem.Solver``` -> ```Solver```; ``:func:`refine.diagnosis.diagnose``` ->
```refine.diagnosis.diagnose```; ``parameters::`` -> ``parameters:``. Left in, a role's colon splits a Google-style ``Returns:`` line
into a type and a description.
"""

from __future__ import annotations

import re

import griffe

ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|data|attr|exc|obj|const):`(~?)([^`]+)`")
LITERAL = re.compile(r"(?<=\S)::$", re.M)  # reST's "text::" before an indented block reads "text:"


def plain(text: str) -> str:
    """``text`` with every Sphinx role replaced by its target as a code span (``~``: the last part)
    and reST's ``::`` that opens a literal block as ``:`` (Markdown takes the indented block as code)."""
    return LITERAL.sub(":", ROLE.sub(lambda m: f"`{m[2].rsplit('.', 1)[-1] if m[1] else m[2]}`", text))


class SphinxRoles(griffe.Extension):
    """Rewrites each object's docstring with :func:`plain` when griffe creates the object."""

    def on_instance(self, *, node, obj, agent, **kwargs) -> None:
        if obj.docstring is not None:
            obj.docstring.value = plain(obj.docstring.value)
