"""The documentation's examples run, and no file names a document the repository lacks.

Rules (stated for writers in docs/index.md, "Writing these docs"):

* every ```python and ```bash / ```sh / ```shell block of README.md and docs/**/*.md runs; the
  blocks of one page run in page order in one fresh temporary directory, the Python blocks in one
  namespace, each shell block with ``bash -e -o pipefail``;
* that directory holds ``usd_scenes``, ``sims`` and ``benchmarks`` (links into the checkout), so
  commands are written as run from the root of a checkout and write their outputs where they run;
* ``python``/``warpshade`` are this interpreter and the tree under test; a ``pip install ...``
  command is not run (the test environment is that install) and neither is ``python -m pytest``
  (this test is part of that suite);
* ```console blocks hold commands too long for the suite (benchmark reproductions, minutes to
  hours), one per ``$ `` line: each names a script that exists and only options that script (or
  the warpshade CLI it drives) defines;
* ```text blocks are output displays and are not run.

Pages that open with the same command (README.md, docs/index.md and the quick start all open with
``warpshade run``, ~90 s of CPU each) run it once per test session: the first page to reach it runs
it, the others wait for it and receive the files it wrote and its exit status (``first_block_run``).
That is only done for a page's first block to run, which always starts from the same fresh
directory, and a run is deterministic: the same scene and options write the same frames.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
FENCE = re.compile(r"^(?P<indent>[ \t]*)(?P<fence>`{3,}|~{3,})(?P<info>[^\n`]*)$")
RUN_PYTHON = {"python", "py"}
RUN_SHELL = {"bash", "sh", "shell"}
CHECKOUT_LINKS = ("usd_scenes", "sims", "benchmarks")


def doc_pages() -> list[Path]:
    """README.md and every Markdown page under docs/."""
    return [ROOT / "README.md"] + sorted((ROOT / "docs").rglob("*.md"))


def code_blocks(path: Path) -> list[tuple[str, int, str]]:
    """``(language, first line number, code)`` of every fenced block of a Markdown file."""
    blocks, lines = [], path.read_text(encoding="utf-8").split("\n")
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        fence, indent = m["fence"], len(m["indent"])
        lang = m["info"].strip().split(" ")[0].split("{")[0].lower()
        body, j = [], i + 1
        while j < len(lines) and not re.match(rf"^[ \t]*{re.escape(fence[0]) * len(fence)}[`~]*[ \t]*$", lines[j]):
            body.append(lines[j][indent:] if lines[j][:indent].strip() == "" else lines[j])
            j += 1
        if j == len(lines):
            raise AssertionError(f"{path.relative_to(ROOT)}:{i + 1}: code block never closed")
        blocks.append((lang, i + 2, "\n".join(body) + "\n"))
        i = j + 1
    return blocks


def _pages_with(langs: set[str]) -> list[Path]:
    return [p for p in doc_pages() if any(lang in langs for lang, _, _ in code_blocks(p))]


def _ids(pages):
    return [str(p.relative_to(ROOT)) for p in pages]


@pytest.fixture
def workdir(tmp_path, monkeypatch):
    """A fresh directory holding ``usd_scenes``, ``sims`` and ``benchmarks`` (links into the checkout),
    made the current directory."""
    for name in CHECKOUT_LINKS:
        os.symlink(ROOT / name, tmp_path / name)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    return tmp_path


RUN_PAGES = _pages_with(RUN_PYTHON | RUN_SHELL)
CONSOLE_PAGES = _pages_with({"console"})


def shell_script(code: str) -> str:
    """The block as bash runs it: ``pip install`` and ``python -m pytest`` commands become ``true``."""
    out = []
    for line in code.replace("\\\n", " ").split("\n"):
        parts = re.split(r"(&&|;)", line)
        for k, part in enumerate(parts):
            words = part.split()
            if words[:2] == ["pip", "install"] or words[:3] in (["python", "-m", "pytest"], ["python", "-m", "pip"]):
                parts[k] = " true "
        out.append("".join(parts))
    return "\n".join(out)


def test_shell_script_rules():
    """The two commands the test does not run are recognised, and nothing else is touched."""
    assert shell_script("pip install -e '.[test]' && warpshade run\n") == " true && warpshade run\n"
    assert shell_script("python -m pytest -q\n").split() == ["true"]
    assert shell_script("warpshade run --frames 2\n") == "warpshade run --frames 2\n"


def shell_env(workdir: Path) -> dict:
    """Environment of the shell blocks: ``python`` and ``warpshade`` are this interpreter and this tree."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
    shims = workdir.parent / f"{workdir.name}-bin"
    shims.mkdir()
    for name, run in (("python", ""), ("python3", ""), ("warpshade", " -m warpshade")):
        (shims / name).write_text(f"#!/bin/sh\nexec {shlex.quote(sys.executable)}{run} \"$@\"\n")
        (shims / name).chmod(0o755)
    env["PATH"] = f"{shims}{os.pathsep}{env.get('PATH', '')}"
    return env


def commands_run(script: str) -> list[str]:
    """The commands of a shell script as ``shell_script`` leaves them, without the ones it made ``true``."""
    parts = re.split(r"&&|;|\n", script)
    return [" ".join(p.split()) for p in parts if p.split() and p.split() != ["true"]]


@pytest.fixture(scope="session")
def block_cache(tmp_path_factory, testrun_uid):
    """A directory shared by every xdist worker of this test session (``testrun_uid`` names it)."""
    root = tmp_path_factory.getbasetemp().parent / f"doc-first-blocks-{testrun_uid}"
    root.mkdir(exist_ok=True)
    return root


def first_block_run(script: str, workdir: Path, env: dict, cache: Path) -> subprocess.CompletedProcess:
    """Run a page's first shell block in ``workdir``, or copy in what the same commands wrote when another
    page ran them in this session (see the module docstring)."""
    key = hashlib.sha256("\n".join(commands_run(script)).encode()).hexdigest()[:16]
    saved, status = cache / key, cache / f"{key}.json"
    with open(cache / f"{key}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # the first page runs, the others wait for its files
        if status.exists():
            shutil.copytree(saved, workdir, symlinks=True, dirs_exist_ok=True)
            return subprocess.CompletedProcess(script, **json.loads(status.read_text()))
        before = set(os.listdir(workdir))
        r = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", script], cwd=workdir, env=env,
                           capture_output=True, text=True, timeout=600)
        saved.mkdir()
        for name in set(os.listdir(workdir)) - before:
            src = workdir / name
            (shutil.copytree if src.is_dir() and not src.is_symlink() else shutil.copy2)(src, saved / name)
        status.write_text(json.dumps({"returncode": r.returncode, "stdout": r.stdout, "stderr": r.stderr}))
        return r


def test_commands_run_rules():
    """The cache key of a block is its commands, whatever ``shell_script`` turned into ``true``."""
    readme = shell_script("pip install -e '.[test]' && warpshade run\npython -m pytest -q -n auto\n")
    quickstart = shell_script("pip install -e '.[test]' && warpshade run\n")
    assert commands_run(readme) == commands_run(quickstart) == ["warpshade run"]
    assert commands_run(shell_script("warpshade run --frames 2\n")) == ["warpshade run --frames 2"]


@pytest.mark.parametrize("page", RUN_PAGES, ids=_ids(RUN_PAGES))
def test_page_examples_run(page, workdir, block_cache):
    """The page's ```python blocks (one namespace) and shell blocks (``bash -e``) run, in page order."""
    namespace = {"__name__": "__main__"}
    env = shell_env(workdir)
    first = True  # nothing has run in workdir yet
    for lang, line, code in code_blocks(page):
        if lang in RUN_PYTHON:
            # Line numbers in a traceback are the page's own lines.
            exec(compile("\n" * (line - 1) + code, str(page), "exec"), namespace)
        elif lang in RUN_SHELL:
            if first:
                r = first_block_run(shell_script(code), workdir, env, block_cache)
            else:
                r = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", shell_script(code)], cwd=workdir, env=env,
                                   capture_output=True, text=True, timeout=600)
        first = first and lang not in RUN_PYTHON | RUN_SHELL
        if lang in RUN_SHELL:
            assert r.returncode == 0, (f"{page.relative_to(ROOT)}:{line}: exit {r.returncode}\n{code}\n"
                                       f"--- stdout\n{r.stdout[-3000:]}\n--- stderr\n{r.stderr[-3000:]}")


def console_problems(cmd: str) -> list[str]:
    """What is wrong with one ``$`` command of a ```console block: a script that does not exist, or
    an ``--option`` that neither the script nor the warpshade package defines."""
    words = shlex.split(cmd)
    while words and re.match(r"^[A-Za-z_]+=", words[0]):  # VAR=value prefixes
        words.pop(0)
    if words[:1] != ["python"]:
        return [f"console commands start with python: {cmd}"]
    sources = sorted((ROOT / "warpshade").rglob("*.py"))
    if words[1:3] != ["-m", "warpshade"]:
        script = ROOT / words[1]
        if not script.is_file():
            return [f"no script {words[1]}"]
        sources.insert(0, script)
    text = "\n".join(f.read_text(encoding="utf-8") for f in sources)
    return [f"option {opt} is defined nowhere" for opt in (w.split("=")[0] for w in words if w.startswith("--"))
            if f'"{opt}"' not in text and f"'{opt}'" not in text]


def test_console_check_finds_bad_commands():
    """The console check fails on a missing script and on an option nobody defines."""
    assert console_problems("python benchmarks/nowhere.py --json x") == ["no script benchmarks/nowhere.py"]
    assert console_problems("python benchmarks/cloth.py --grid 8 --gird 8") == ["option --gird is defined nowhere"]
    assert console_problems("OPENBLAS_NUM_THREADS=1 python -m warpshade bench --quick --out d") == []


@pytest.mark.parametrize("page", CONSOLE_PAGES, ids=_ids(CONSOLE_PAGES))
def test_console_commands_exist(page):
    """Each ``$`` command of a ```console block names an existing script and only options it defines."""
    problems = []
    for lang, line, code in code_blocks(page):
        if lang != "console":
            continue
        for k, cmd in enumerate(code.replace("\\\n", " ").split("\n")):
            if cmd.startswith("$ "):
                problems += [f"{page.relative_to(ROOT)}:{line + k}: {p}" for p in console_problems(cmd[2:])]
    assert not problems, "\n".join(problems)


def tracked_files() -> list[Path]:
    """Files git tracks (or, outside a git checkout, every file but caches and build output)."""
    try:
        out = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
        return [ROOT / f for f in out.decode().split("\0") if f]
    except (OSError, subprocess.CalledProcessError):
        skip = {".git", "__pycache__", "site", ".venv-ci", ".warpshade-cache"}
        return [p for p in ROOT.rglob("*") if p.is_file() and not skip & set(p.relative_to(ROOT).parts)]


DOC_REF = re.compile(r"(?<![\w/.-])((?:[\w.-]+/)*[\w.-]+\.md)\b|(?<![\w/.-])(docs/[\w./-]*[\w/])")
TEXT_SUFFIXES = {".md", ".py", ".toml", ".yml", ".yaml", ".txt", ".cfg", ".usda", ""}


def _mentions(pattern):
    """``(file, line number, reference, text before it)`` for every match of ``pattern`` (its first
    non-empty group) in the tracked text files but this one, which names absent files on purpose."""
    for f in tracked_files():
        if f == Path(__file__).resolve() or f.suffix not in TEXT_SUFFIXES or not f.is_file():
            continue
        try:
            text = f.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue
        for n, line in enumerate(text.split("\n"), 1):
            for m in pattern.finditer(line):
                yield f, n, next(g for g in m.groups() if g), line[max(0, m.start() - 80):m.start()]


def test_no_file_names_a_missing_document():
    """Every ``*.md`` file and ``docs/...`` path a tracked file mentions exists (relative to the root
    or to the file; a bare file name anywhere in the tree)."""
    names = {p.name for p in tracked_files()} | {p.name for p in (ROOT / "docs").rglob("*")}
    missing = []
    for f, n, ref, before in _mentions(DOC_REF):
        ref = ref.split("#")[0].rstrip(".")
        if "://" in before and "/" in ref:
            continue  # part of a URL
        if "/" not in ref:
            ok = ref in names
        else:
            ok = any((base / ref).exists() for base in (ROOT, f.parent))
        if not ok:
            missing.append(f"{f.relative_to(ROOT)}:{n}: {ref}")
    assert not missing, "documents named but absent:\n" + "\n".join(missing)


REPO_REF = re.compile(r"(?<![\w/.-])((?:tests|benchmarks|sims|warpshade|usd_scenes)/[\w./-]*\.[a-z]+)\b")
"""A path into the repository's own folders (``tests/cli/test_run.py``, ``benchmarks/cloth.py``, ...)."""


def _ignored(paths: list[str]) -> set[str]:
    """The paths git ignores (outputs a command writes, caches), which a text may name without them existing."""
    # each path also as a folder, which a folder pattern ("cache/") matches only with its slash
    out = subprocess.run(["git", "check-ignore", "--no-index", "--stdin"], cwd=ROOT,
                         input="\n".join(q for p in paths for q in (p, p + "/")), capture_output=True, text=True)
    return {p.rstrip("/") for p in out.stdout.split()}


def test_no_file_names_a_missing_repository_file():
    """Every path into tests/, benchmarks/, sims/, warpshade/ or usd_scenes/ that a tracked file names
    exists (relative to the root or to the file), unless git ignores it (an output or a cache)."""
    missing = []
    for f, n, ref, before in _mentions(REPO_REF):
        ref = ref.rstrip(".")
        if "://" in before:
            continue  # part of a URL
        if not any((base / ref).exists() for base in (ROOT, f.parent)):
            missing.append((f"{f.relative_to(ROOT)}:{n}", ref))
    ignored = _ignored([ref for _, ref in missing]) if missing else set()
    missing = [f"{where}: {ref}" for where, ref in missing if ref not in ignored]
    assert not missing, "repository files named but absent:\n" + "\n".join(missing)


def test_repository_path_check_finds_a_missing_file():
    """The pattern above catches the paths it is meant to, and git's ignore rules are read."""
    found = [m.group(1) for m in REPO_REF.finditer("see tests/cli/test_run.py::test_x, `benchmarks/nowhere.py` and "
                                                   "sims/flag_shaded.usdc; not docs/x.py or mytests/a.py")]
    assert found == ["tests/cli/test_run.py", "benchmarks/nowhere.py", "sims/flag_shaded.usdc"]
    assert _ignored(found) == {"sims/flag_shaded.usdc"}


def test_reference_check_finds_a_missing_document(tmp_path):
    """The pattern above catches the references it is meant to (a check that cannot fail proves nothing)."""
    found = [(m.group(1) or m.group(2)) for m in DOC_REF.finditer(
        f"see {OLD_CONVENTIONS}.md §2, docs/guide/nowhere.md and `docs/images/x.png`; not foo.mdx or a.md5")]
    assert found == [f"{OLD_CONVENTIONS}.md", "docs/guide/nowhere.md", "docs/images/x.png"]


OLD_CONVENTIONS = "CONT" + "RACTS"
"""Stem of the file the conventions came from, spelled in two pieces so this file does not cite it."""


def test_no_citation_of_the_old_contracts_file():
    """The conventions live in docs/conventions.md; nothing cites the file they came from."""
    hits = [str(f.relative_to(ROOT)) for f in tracked_files()
            if f.suffix in TEXT_SUFFIXES and f.is_file() and OLD_CONVENTIONS in f.read_text(encoding="utf-8", errors="replace")]
    assert not hits, hits
