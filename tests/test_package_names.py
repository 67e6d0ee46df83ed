"""``warpshade``'s public names: loaded on first use (``_LAZY``) and imported statically under
``TYPE_CHECKING`` for type checkers and the API docs (mkdocstrings reads the source, not the running
module); the two lists must name the same things from the same modules."""

import ast
import os

import warpshade


def _type_checking_imports() -> dict[str, str]:
    """name -> submodule, from the ``if TYPE_CHECKING:`` block of warpshade/__init__.py."""
    with open(os.path.join(os.path.dirname(warpshade.__file__), "__init__.py")) as f:
        tree = ast.parse(f.read())
    found = {}
    for node in tree.body:
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
            for imp in node.body:
                assert isinstance(imp, ast.ImportFrom) and imp.level == 1
                for alias in imp.names:
                    found[alias.asname or alias.name] = imp.module or alias.name
    return found


def test_type_checking_block_names_the_lazy_names_from_the_same_modules():
    static = _type_checking_imports()
    lazy = dict(warpshade._SOURCE)
    lazy["script"] = "script"  # a submodule, loaded by __getattr__'s fallback
    assert static == lazy


def test_every_public_name_loads():
    for name in warpshade.__all__:
        assert getattr(warpshade, name) is not None, name
