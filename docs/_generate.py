"""Reference pages written from the code at every docs build (called by ``conf.py``).

- ``reference/api/``: one page per subpackage that has an ``__all__``, with an autosummary of
  every name in it (autosummary writes one page per name), and a page for ``pacam_render``
  itself whose table links each top-level name to the page of the object it is. A top-level
  name that no subpackage exports gets its own page.
- ``reference/cli/``: one page per ``pacam`` command, from the real parser
  (:func:`pacam_render.cli.build_parser`) through sphinx-argparse.

The generated folders are build products (``.gitignore``); ``tests/docs/test_docs_site.py``
checks that the built site has a page for every public name and every command.
"""

from __future__ import annotations

import argparse
import functools
import importlib
import pkgutil
import re
from pathlib import Path
from types import ModuleType

import pacam_render

# |s|, |a_i|, |beta| in docstrings are absolute values, not reST substitutions; ``literals``
# and :math:`...` are left as they are.
_LITERAL = re.compile(r"(``.*?``|:math:`[^`]*`|`[^`]*`)")
_BARS = re.compile(r"(?<![|\\])\|(?=[^|\s])([^|`]*?[^|\s])\|(?!\|)")

DOCS = Path(__file__).resolve().parent
API = DOCS / "reference" / "api"
CLI = DOCS / "reference" / "cli"
DESIGN_FILE = DOCS / "reference" / "design_file.md"


def subpackages() -> list[str]:
    """The names of the subpackages of pacam_render that declare a public ``__all__``."""
    out = []
    for info in pkgutil.iter_modules(pacam_render.__path__):
        if not info.ispkg:
            continue
        module = importlib.import_module(f"pacam_render.{info.name}")
        if getattr(module, "__all__", None):
            out.append(f"pacam_render.{info.name}")
    return sorted(out)


@functools.cache
def canonical_names() -> dict[str, str]:
    """Each public name of ``pacam_render.__all__`` -> the full name its page is under.

    The page is the subpackage's when a subpackage exports the same object (under any name),
    the module's own for a module, and ``pacam_render.NAME`` otherwise.
    """
    exported = []
    for sub in subpackages():
        module = importlib.import_module(sub)
        exported += [(sub, name, getattr(module, name)) for name in module.__all__]
    out = {}
    for name in pacam_render.__all__:
        obj = getattr(pacam_render, name)
        if isinstance(obj, ModuleType):
            out[name] = obj.__name__
            continue
        same = [f"{sub}.{n}" for sub, n, o in exported if o is obj]
        same.sort(key=lambda full: full.rsplit(".", 1)[1] != name)  # same name first
        out[name] = same[0] if same else f"pacam_render.{name}"
    return out


def _write(path: Path, text: str) -> None:
    """Write ``text`` unless the file already holds it (so Sphinx sees no change)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)


def _title(text: str, char: str = "=") -> str:
    return f"{text}\n{char * len(text)}\n"


def api_pages() -> dict[str, str]:
    """File name under reference/api -> reStructuredText."""
    pages: dict[str, str] = {}
    subs = subpackages()
    canon = canonical_names()
    own = sorted(n for n, full in canon.items() if full == f"pacam_render.{n}")
    modules = sorted(
        {full for n, full in canon.items() if isinstance(getattr(pacam_render, n), ModuleType)}
    )
    aliases = sorted(n for n in canon if n not in own and canon[n] not in modules)
    top = [
        _title("pacam_render"),
        ".. automodule:: pacam_render\n   :no-members:\n",
        _title("Top-level names", "-"),
        "``import pacam_render as pr`` gives these names. Most are the same objects as a "
        "subpackage exports, and link to their page there.\n",
        ".. autosummary::\n   :nosignatures:\n",
        *[f"   ~{canon[n].removeprefix('pacam_render.')}" for n in aliases],
        "",
    ]
    renamed = [n for n in aliases if canon[n].rsplit(".", 1)[1] != n]
    if renamed:
        top += [
            "Names that the top level exports under another name:\n",
            *[f"- ``pacam_render.{n}`` is :py:obj:`{canon[n]}`" for n in renamed],
            "",
        ]
    if own:
        top += [
            "Names that only the top level exports:\n",
            ".. autosummary::\n   :toctree: generated\n   :nosignatures:\n",
            *[f"   {n}" for n in own],
            "",
        ]
    if modules:
        top += [
            "Modules:\n",
            ".. autosummary::\n   :toctree: generated\n   :nosignatures:\n",
            *[f"   {m.removeprefix('pacam_render.')}" for m in modules],
            "",
        ]
    pages["pacam_render.rst"] = "\n".join(top)
    for sub in subs:
        module = importlib.import_module(sub)
        body = [
            _title(f"pacam_render.{sub.rsplit('.', 1)[1]}"),
            f".. automodule:: {sub}\n   :no-members:\n",
            _title("Public names", "-"),
            ".. autosummary::\n   :toctree: generated\n   :nosignatures:\n",
            *[f"   {n}" for n in sorted(module.__all__)],
            "",
        ]
        pages[f"{sub}.rst"] = "\n".join(body)
    index = [
        _title("Python API"),
        "Every public name: ``pacam_render.__all__`` and each subpackage's ``__all__``, one "
        "page per name, written from the docstrings (numpydoc). Units are in the names: scene "
        "mm, time ms, image px.\n",
        ".. toctree::\n   :maxdepth: 1\n",
        "   pacam_render",
        *[f"   {sub}" for sub in subs],
        "",
    ]
    pages["index.rst"] = "\n".join(index)
    return pages


def commands() -> list[str]:
    """The ``pacam`` commands, in the order ``pacam --help`` lists them."""
    from pacam_render.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return list(sub.choices)


def _help_bars() -> str:
    """reST substitutions that keep ``|s|`` in the commands' help as written (sphinx-argparse
    reads help as reST, where ``|s|`` would be an undefined substitution)."""
    from pacam_render.cli import build_parser

    texts = []
    stack = [build_parser()]
    while stack:
        parser = stack.pop()
        texts.append(parser.description or "")
        for action in parser._actions:
            texts.append(str(action.help or ""))
            if isinstance(action, argparse._SubParsersAction):
                stack += list(action.choices.values())
    found = sorted(set(_BARS.findall(" ".join(texts))))
    return "".join(f".. |{w}| replace:: \\|{w}\\|\n" for w in found)


def cli_pages() -> dict[str, str]:
    """File name under reference/cli -> reStructuredText, from the real parser."""
    directive = _help_bars() + (
        "\n.. argparse::\n   :module: pacam_render.cli\n   :func: build_parser\n   :prog: pacam\n"
    )
    pages = {"pacam.rst": "\n".join([_title("pacam"), directive + "   :nosubcommands:\n", ""])}
    for name in commands():
        pages[f"pacam-{name}.rst"] = "\n".join(
            [_title(f"pacam {name}"), directive + f"   :path: {name}\n", ""]
        )
    index = [
        _title("Command line"),
        "Every ``pacam`` command, its flags and their defaults, generated from the parser the "
        "command itself uses (``pacam_render.cli.build_parser``). ``pacam COMMAND --help`` "
        "prints the same.\n",
        ".. toctree::\n   :maxdepth: 1\n",
        "   pacam",
        *[f"   pacam-{name}" for name in commands()],
        "",
    ]
    pages["index.rst"] = "\n".join(index)
    return pages


def design_file_page() -> str:
    """reference/design_file.md: every design-file key (:mod:`pacam_render.model.design_keys`),
    the prototype's file as ``pacam design`` writes it, and the mask images' conventions (the
    docstring of :mod:`pacam_render.model.masks`)."""
    from pacam_render.model import masks
    from pacam_render.model.camera import prototype
    from pacam_render.model.design_file import design_toml
    from pacam_render.model.design_keys import key_rows

    rows = key_rows()
    cols = list(rows[0])
    table = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    table += ["| " + " | ".join(f"`{r[c]}`" if c == "key" else r[c] for c in cols) + " |"
              for r in rows]  # fmt: skip
    doc = masks.__doc__.split("\n\nNumpy only")[0]
    return "\n".join([
        "# Design file keys",
        "",
        "A camera design is one TOML file (`pacam design --write FILE`) that every command takes "
        "with `--design FILE` ([how-to](../howto/own_camera.md)). Each key, its unit, its "
        "default (the paper's prototype), the values it may take and the `pacam design` flag "
        "that sets it; a key no flag sets is edited in the file. An error about a file names "
        "its key (`[exposure] exposure_ms`); an error about a flag names the flag. Generated "
        "from `pacam_render.model.design_keys` at every docs build; a test checks the list "
        "against the keys the reader accepts.",
        "",
        *table,
        "",
        "## The prototype's file",
        "",
        "`pacam design --write proto.toml` with no other flag writes:",
        "",
        "```toml",
        design_toml(prototype()).rstrip(),
        "```",
        "",
        "## Mask images (`[schedule] kind = \"bitmap\"`)",
        "",
        "Any size: each image pixel is one display pixel of `[lcos] pitch_mm`, and the image's "
        "centre is the optical axis, so an image of the prototype's display is 1280x1024 and a "
        "smaller one covers the middle of the display. Every open pixel must lie inside the "
        "lens (`[lens] R_max_mm` from the axis): the reader names the patterns that do not. "
        "All the images of one folder must have one size; they are read in name order, one "
        "per pattern. 8- and 16-bit images are grey levels (level / 255 or / 65535, no gamma "
        "decoding); colour images are read as the Rec. 709 luminance of their code values.",
        "",
        "From `pacam_render.model.masks`:",
        "",
        "```text",
        doc.strip(),
        "```",
        "",
    ])  # fmt: skip


def write_reference_pages(app=None) -> None:
    """Write the API and CLI pages and the design file's keys (Sphinx's ``builder-inited``)."""
    _write(DESIGN_FILE, design_file_page())
    for folder, pages in ((API, api_pages()), (CLI, cli_pages())):
        for name, text in pages.items():
            _write(folder / name, text)
        stale = {p.name for p in folder.glob("*.rst")} - set(pages)
        for name in stale:
            (folder / name).unlink()


@functools.cache
def _attribute_docs(module: str) -> dict[str, list[str]]:
    """The attribute docstrings (a string literal after an assignment) of ``module`` and, for a
    package, of every module below it, by name."""
    from sphinx.pycode import ModuleAnalyzer

    mod = importlib.import_module(module)
    names = [module]
    if hasattr(mod, "__path__"):
        names += [i.name for i in pkgutil.walk_packages(mod.__path__, module + ".")]
    out: dict[str, list[str]] = {}
    for m in reversed(names):  # the package's own last, so it wins
        try:
            docs = ModuleAnalyzer.for_module(m).find_attr_docs()
        except Exception:  # a module that cannot be analysed: no attribute docs from it
            continue
        out.update({attr: list(doc) for (cls, attr), doc in docs.items() if not cls})
    return out


def constant_docs(app, what, name, obj, options, lines) -> None:
    """A constant re-exported by a package shows its own attribute docstring, not its type's
    ("Convert a string or number to a floating point number", ``autodoc-process-docstring``)."""
    own = type(obj).__doc__
    first = next((s.strip() for s in lines if s.strip()), "")
    if what not in ("data", "attribute") or not first or not isinstance(own, str):
        return
    if first != own.strip().splitlines()[0].strip():  # numpydoc puts a blank line first
        return
    module, attr = name.rsplit(".", 1)
    doc = _attribute_docs(module).get(attr)
    if doc:
        lines[:] = doc


def escape_bars(app, what, name, obj, options, lines) -> None:
    """Escape ``|x|`` (an absolute value) in a docstring (``autodoc-process-docstring``)."""
    for i, line in enumerate(lines):
        parts = _LITERAL.split(line)
        lines[i] = "".join(
            p if k % 2 else _BARS.sub(lambda m: rf"\|{m.group(1)}\|", p)
            for k, p in enumerate(parts)
        )


def _py_objects(env) -> dict[str, list[str]]:
    """Every documented Python object's last name (and dotted tails) -> its full names."""
    out: dict[str, list[str]] = {}
    for full in env.get_domain("py").objects:
        parts = full.split(".")
        for k in range(1, len(parts)):
            out.setdefault(".".join(parts[k:]), []).append(full)
    return out


def resolve_reference(app, env, node, contnode):
    """Resolve a Python reference that Sphinx did not (``missing-reference``).

    - ``pacam_render.NAME`` -> the page of the object it is (a subpackage's, see
      :func:`canonical_names`).
    - A short or relative name in a docstring (``select_variant``, ``fourier.taper_pad``) -> the
      one public object of that name, when there is exactly one.
    - Otherwise, in the API pages only: the docstrings name private modules and helpers, which
      have no page; such a name is shown as code, without a link. Everywhere else (the pages
      written by hand) an unresolved reference stays an error.
    """
    if node.get("refdomain") != "py":
        return None
    domain = env.get_domain("py")
    target = node.get("reftarget", "")
    name = target.removeprefix("pacam_render.")
    canon = canonical_names()
    if name != target and name in canon and canon[name] != target:
        return domain.resolve_xref(
            env, node["refdoc"], app.builder, node["reftype"], canon[name], node, contnode
        )
    found = _py_objects(env).get(target.lstrip("~.").removeprefix("pacam_render."), [])
    if len(set(found)) == 1:
        return domain.resolve_xref(
            env, node["refdoc"], app.builder, "obj", found[0], node, contnode
        )
    if node["refdoc"].startswith("reference/api/"):
        return contnode
    return None
