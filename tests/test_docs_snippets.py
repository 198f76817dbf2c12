"""Every command and Python snippet of README.md and docs/*.md runs as written.

The fenced blocks are found in every Markdown file at collection time (docs written later are
tested without touching this file):

- a ``python`` block is one plain script: written to ``snippet.py`` in a fresh workspace and run
  with ``python snippet.py`` (a new process, as a user would run it: worker processes, the
  ``__main__`` guard and all);
- a ``bash`` / ``sh`` / ``console`` / ``shell`` or unlabelled block contributes its lines that
  start with ``downhole`` (``\\`` continuations joined, ``# comments`` dropped): each such
  command is one test, run through ``downhole.cli.main`` in a fresh workspace; it must exit 0.
  Commands of the same file that wrote an ``--out`` path the command reads are run first.
  Other lines (``make``, ``openssl``, ``export``) and output listings are not commands.

The workspace is a temporary folder with ``examples/`` of the repository, so the paths of the
docs (``examples/...``, ``out/...``) work as written.

A block can be marked by HTML comments (invisible in the rendered page) on the lines before it:

- ``<!-- docs-test: slow -->``: a long block, run by ``make test-slow`` (``-m slow``);
- ``<!-- docs-test: skip REASON -->``: not run, with the reason (only for what cannot run in a
  test: a second host, a browser, a human);
- ``<!-- docs-test: file NAME -->``: the block is the content of the file NAME, which every
  other block of the same document finds in its workspace (e.g. a controller file that a
  command loads); the block itself is compiled, not run.

Commands are also matched against :data:`COMMANDS` (a prefix of the command, per document):
``"slow"`` or ``"skip: REASON"``. Every skip has its reason.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SHELL_LANGS = {"", "bash", "sh", "console", "shell", "shell-session"}
MARKER = re.compile(r"<!--\s*docs-test:\s*(\w+)\s*(.*?)\s*-->")

#: per-command treatment, by document (relative path) and command prefix: "slow" or
#: "skip: REASON". Keep every skip's reason precise.
COMMANDS: dict[str, dict[str, str]] = {
    "README.md": {
        "downhole simulate examples/table_5_1.toml --fidelity hybrid": "slow",
        "downhole reproduce fig2.3 stickslip-lumped": "slow",
        "downhole optimize dp": "slow",
        "downhole design eid": "slow",
        "downhole compare-controllers --suite smoke": "slow",
        "downhole bench --quick": "slow",
        "downhole sil examples/sil_dashboard_lumped.toml --dashboard": "skip: waits for Start "
        "on the page and serves until Ctrl-C (tests/test_dashboard_operator.py drives it with "
        "Chromium and runs the command in a subprocess)",
    },
    "docs/compare-controllers.md": {
        "downhole compare-controllers": "slow",
    },
    "docs/dp.md": {
        "downhole optimize dp": "slow",
    },
    "docs/observer.md": {
        "downhole reproduce observer-surface --out": "skip: the full-size experiment takes "
        "~3 min on 2 cores alone; its --quick form below runs (slow)",
        "downhole reproduce observer-surface --quick": "slow",
    },
    "docs/reproduce.md": {
        "downhole reproduce --all --out": "skip: every experiment at full size takes hours",
        "downhole reproduce --all --quick": "skip: every experiment, reduced: tens of minutes on "
        "2 cores (make test-slow runs the experiments' own quick tests)",
        "downhole reproduce fig2.3 table5.2": "slow",
        "downhole reproduce --chapter 3": "slow",
    },
    "docs/sil.md": {
        "downhole sil examples/sil_pi_hybrid68.toml --dashboard": "skip: serves the dashboard "
        "until a browser stops it (tests/test_dashboard.py drives it with Chromium)",
        "downhole sil examples/sil_dhp_hybrid68.toml --remote": "skip: the plant end of a UDP "
        "link waits for a controller started in a second shell (tests/test_sil_cli.py runs "
        "both ends)",
        "downhole sil-controller": "skip: the controller end of a UDP link needs the plant "
        "running in another process or host (tests/test_sil_cli.py runs both ends)",
        "downhole sil scenario.toml --remote --link-key-file": "skip: needs two hosts and a "
        "shared key file (tests/test_sil_security.py covers the authenticated link)",
        "downhole sil examples/sil_dashboard_lumped.toml --dashboard": "skip: waits for Start "
        "on the page and serves until Ctrl-C (tests/test_dashboard_operator.py drives it with "
        "Chromium and runs the command in a subprocess)",
        "downhole sil examples/sil_pi_hybrid68.toml --dashboard --http-port": "skip: serves "
        "until Ctrl-C after the run (tests/test_dashboard_operator.py: the server stays up)",
        "downhole sil examples/sil_pi_hybrid68.toml --dashboard --autostart --exit-after-run":
        "slow",
        "downhole sil examples/sil_pi_hybrid68.toml --controller": "slow",
        "downhole export-fmu": "slow",
    },
    "docs/sweeps.md": {
        "downhole sweep examples/sweep_stability_map.toml --out": "slow",
        "downhole sweep examples/nominal_table_2_1.toml": "slow",
        "downhole sweep examples/sweep_montecarlo.toml": "slow",
        "downhole sweep examples/sweep_stability_map.toml --local-cluster": "slow",
        "downhole sweep examples/sweep_stability_map.toml --scheduler tcp://": "skip: needs a "
        "running Dask scheduler at the address (the --local-cluster line above starts one)",
        "downhole export out/stability_map": "slow",
    },
}


@dataclass
class Block:
    doc: str          # path relative to the repository
    line: int         # 1-based line of the opening fence
    lang: str
    text: str
    markers: list = field(default_factory=list)  # (kind, argument)

    def marker(self, kind):
        return next((arg for k, arg in self.markers if k == kind), None)


def parse_blocks(path: Path) -> list[Block]:
    """Fenced blocks of a Markdown file, with the docs-test markers of the lines before each."""
    lines = path.read_text(encoding="utf-8").splitlines()
    rel = path.relative_to(ROOT).as_posix()
    blocks, pending, i = [], [], 0
    while i < len(lines):
        stripped = lines[i].strip()
        m = MARKER.search(stripped)
        if m:
            pending.append((m.group(1), m.group(2)))
            i += 1
            continue
        fence = re.match(r"^(`{3,}|~{3,})\s*([\w+-]*)", stripped)
        if fence:
            mark, lang = fence.group(1), fence.group(2).lower()
            indent = len(lines[i]) - len(lines[i].lstrip())
            body, j = [], i + 1
            while j < len(lines) and not lines[j].strip().startswith(mark):
                body.append(lines[j][indent:] if lines[j][:indent].strip() == "" else lines[j])
                j += 1
            blocks.append(Block(rel, i + 1, lang, "\n".join(body) + "\n", pending))
            pending, i = [], j + 1
            continue
        if stripped:
            pending = []  # markers apply to the block right after them (blank lines allowed)
        i += 1
    return blocks


def commands_of(block: Block) -> list[str]:
    """The ``downhole ...`` command lines of a shell block (continuations joined)."""
    out, buf = [], ""
    for raw in block.text.splitlines():
        line = raw.rstrip()
        if buf:
            buf += " " + line.strip()
        elif line.lstrip().startswith("downhole ") or line.strip() == "downhole":
            buf = line.strip()
        else:
            continue
        if buf.endswith("\\"):
            buf = buf[:-1].rstrip()
            continue
        out.append(buf)
        buf = ""
    return out


def argv_of(command: str) -> list[str]:
    return shlex.split(command, comments=True)[1:]


def _treatment(doc: str, command: str) -> str | None:
    table = COMMANDS.get(doc, {})
    best = max((p for p in table if command.startswith(p)), key=len, default=None)
    return table[best] if best is not None else None


def _out_path(argv: list[str]) -> str | None:
    for k, a in enumerate(argv[:-1]):
        if a == "--out":
            return argv[k + 1]
    return None


def _collect():
    python, shell, files = [], [], {}
    for path in DOCS:
        blocks = parse_blocks(path)
        doc_commands = []
        for b in blocks:
            name = b.marker("file")
            if name:
                files.setdefault(b.doc, []).append((name, b.text, b.line))
                python.append(("file", b, None))
                continue
            if b.lang == "python":
                python.append(("python", b, None))
            elif b.lang in SHELL_LANGS:
                for c in commands_of(b):
                    doc_commands.append((b, c))
                    shell.append(("command", b, (c, list(doc_commands))))
    return python, shell, files


PYTHON_BLOCKS, COMMAND_ITEMS, DOC_FILES = _collect()


def _params(items):
    out = []
    for kind, b, extra in items:
        marks = []
        skip = b.marker("skip")
        slow = b.marker("slow") is not None
        if kind == "command":
            t = _treatment(b.doc, extra[0])
            if t == "slow":
                slow = True
            elif t is not None and t.startswith("skip:"):
                skip = t[5:].strip()
        if skip is not None:
            assert skip, f"{b.doc}:{b.line}: a docs-test skip needs a reason"
            marks.append(pytest.mark.skip(reason=f"{b.doc}:{b.line}: {skip}"))
        if slow:
            marks.append(pytest.mark.slow)
        label = f"{b.doc}:{b.line}" + (f":{' '.join(argv_of(extra[0])[:3])}"
                                       if kind == "command" else "")
        out.append(pytest.param(kind, b, extra, marks=marks, id=label))
    return out


@pytest.fixture
def workspace(tmp_path, monkeypatch):
    (tmp_path / "examples").symlink_to(ROOT / "examples", target_is_directory=True)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    return tmp_path


def _write_doc_files(doc: str, ws: Path):
    for name, text, _ in DOC_FILES.get(doc, []):
        (ws / name).parent.mkdir(parents=True, exist_ok=True)
        (ws / name).write_text(text)


def _env():
    return dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""),
                MPLBACKEND="Agg", PYTHONWARNINGS="ignore::DeprecationWarning")


@pytest.mark.parametrize("kind, block, extra", _params(PYTHON_BLOCKS))
def test_python_snippet_runs(kind, block, extra, workspace):
    if kind == "file":
        compile(block.text, block.marker("file"), "exec")  # it is Python; used by later blocks
        return
    _write_doc_files(block.doc, workspace)
    script = workspace / "snippet.py"
    script.write_text(block.text)
    p = subprocess.run([sys.executable, str(script)], cwd=workspace, env=_env(),
                       capture_output=True, text=True, timeout=1800)
    assert p.returncode == 0, (f"{block.doc}:{block.line}: the snippet failed as written:\n"
                               f"{p.stderr[-4000:]}")


def _run_cli(argv: list[str], what: str):
    from downhole.cli import main

    try:
        code = main(argv)
    except SystemExit as exc:  # typer's standalone mode
        code = exc.code
    assert code in (0, None), f"{what}: exit code {code}"


@pytest.mark.parametrize("kind, block, extra", _params(COMMAND_ITEMS))
def test_command_runs(kind, block, extra, workspace):
    command, so_far = extra
    argv = argv_of(command)
    _write_doc_files(block.doc, workspace)
    # earlier commands of the document whose --out this command reads (e.g. simulate, export)
    for b, earlier in so_far[:-1]:
        out = _out_path(argv_of(earlier))
        if out and any(a == out or a.startswith(out.rstrip("/") + "/") for a in argv):
            _run_cli(argv_of(earlier), f"{b.doc}:{b.line}: `{earlier}` (needed by `{command}`)")
    _run_cli(argv, f"{block.doc}:{block.line}: `{command}`")


def test_the_docs_have_snippets_and_markers_parse():
    """The collector sees the documents (a parse regression would silently test nothing)."""
    assert len(PYTHON_BLOCKS) >= 10 and len(COMMAND_ITEMS) >= 20
    for kind, b, extra in PYTHON_BLOCKS + COMMAND_ITEMS:
        for k, arg in b.markers:
            assert k in ("slow", "skip", "file"), f"{b.doc}:{b.line}: unknown docs-test marker {k}"
    for doc, table in COMMANDS.items():
        assert (ROOT / doc).exists(), doc
        cmds = [extra[0] for kind, b, extra in COMMAND_ITEMS if b.doc == doc]
        for prefix in table:
            assert any(c.startswith(prefix) for c in cmds), f"{doc}: no command {prefix!r}"
