"""The docs run: every fenced ``bash``/``sh`` and ``python`` block of the README, getting-started,
the tutorials and the quality page is run, in the page's order, in a copy of the demo project the
end-to-end test builds (one copy per page, so a page's blocks see what its earlier blocks did).

A block a demo cannot run (a server that waits for Ctrl+C, a Ray cluster, another project's code)
says so where a reader sees it: the paragraph just before it holds ``(not run by the docs test:
REASON)``, and the block is skipped with that reason. Each block runs on its own, as a reader
pasting it would: bash with ``-e``, Python in a fresh interpreter, both in the project's folder
with this environment's ``dance3d`` and ``dvc`` on the PATH. pytest's report lists every block as
passed or skipped with its reason (``-ra``).
"""

from __future__ import annotations

import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.conftest import PROJECT, demo_copy, tool_environment

PAGES = [PROJECT / "README.md", PROJECT / "docs/getting-started.md",
         *sorted((PROJECT / "docs/tutorials").glob("*.md")), PROJECT / "docs/quality.md"]
RUNNABLE = {"bash": "bash", "sh": "bash", "python": "python"}
FENCE = re.compile(r"^```(\w*)\s*$")
NOT_RUN = re.compile(r"\(not run by the docs test: ([^)]*)\)", re.S)


@dataclass(frozen=True)
class Block:
    """One fenced code block of a page: where it starts, its language, its code, and why it is not
    run (None: it is)."""

    page: Path
    line: int
    language: str
    code: str
    not_run: str | None

    @property
    def name(self) -> str:
        return f"{self.page.name}:{self.line}"


def blocks_of(page: Path) -> list[Block]:
    """The fenced blocks of a Markdown page in order, each with the reason its preceding paragraph
    gives for not running it."""
    lines = page.read_text().splitlines()
    blocks, i = [], 0
    while i < len(lines):
        opened = FENCE.match(lines[i])
        if not opened:
            i += 1
            continue
        end = next(j for j in range(i + 1, len(lines)) if lines[j].startswith("```"))
        before = []  # the paragraph just before the fence
        for j in range(i - 1, -1, -1):
            if not lines[j].strip():
                if before:
                    break
                continue
            before.insert(0, lines[j])
        reason = NOT_RUN.search(" ".join(before))
        blocks.append(Block(page, i + 1, opened.group(1), "\n".join(lines[i + 1:end]) + "\n",
                            " ".join(reason.group(1).split()) if reason else None))
        i = end + 1
    return blocks


def run_block(block: Block, root: Path, env: dict[str, str]) -> subprocess.CompletedProcess:
    """Run a bash or Python block in ``root`` as a reader would."""
    command = (["bash", "-e", "-o", "pipefail", "-c", block.code] if RUNNABLE[block.language] == "bash"
               else [sys.executable, "-c", block.code])
    return subprocess.run(command, cwd=root, env=env, capture_output=True, text=True, timeout=900)


def reader_environment(home: Path) -> dict[str, str]:
    """This environment's executables first on the PATH, a git identity, and Hugging Face and
    matplotlib caches of the test's own."""
    return {**tool_environment(), "HF_HOME": str(home / "hf"),
            "MPLCONFIGDIR": str(home / "mpl"), "GIT_AUTHOR_NAME": "docs test", "GIT_AUTHOR_EMAIL": "docs@test",
            "GIT_COMMITTER_NAME": "docs test", "GIT_COMMITTER_EMAIL": "docs@test", "COLUMNS": "100"}


BLOCKS = [b for page in PAGES for b in blocks_of(page) if b.language in RUNNABLE]


@pytest.fixture(scope="session")
def page_projects(built_demo: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[Path, Path]:
    """One copy of the built demo per page, made when the page's first block runs."""

    class Copies(dict):
        def __missing__(self, page: Path) -> Path:
            self[page] = demo_copy(built_demo, tmp_path_factory.mktemp(page.stem) / "dance3d")
            return self[page]

    return Copies()


@pytest.mark.slow
@pytest.mark.parametrize("block", BLOCKS, ids=[f"{b.name} {b.language}" for b in BLOCKS])
def test_every_docs_block_runs_on_the_demo(block: Block, page_projects: dict[Path, Path],
                                           tmp_path_factory: pytest.TempPathFactory) -> None:
    if block.not_run:
        pytest.skip(f"{block.name}: {block.not_run}")
    root = page_projects[block.page]
    done = run_block(block, root, reader_environment(tmp_path_factory.getbasetemp() / "reader"))
    assert done.returncode == 0, (f"{block.name} ({block.language}) failed with exit code {done.returncode}:\n"
                                  f"{block.code}\n--- stderr ---\n{done.stderr[-3000:]}\n--- stdout ---\n"
                                  f"{done.stdout[-1500:]}")


def test_the_pages_have_blocks_to_run_and_say_why_the_others_are_not() -> None:
    pages = {b.page.name for b in BLOCKS if not b.not_run}
    assert {"README.md", "getting-started.md", "loading.md", "exporting.md", "annotating.md", "quality.md"} <= pages
    # `make demo` would build a second demo inside the first, `make test` run this test inside itself
    assert [b.name for b in BLOCKS if re.search(r"\bmake (demo|test)\b", b.code) and not b.not_run] == []
    assert all(len(b.not_run) > 20 for b in BLOCKS if b.not_run)  # a reason, not a bare flag


def test_a_block_is_found_with_its_line_language_and_reason(tmp_path: Path) -> None:
    page = tmp_path / "page.md"
    page.write_text("Intro.\n\n```bash\necho one\n```\n\nA server (not run by the docs test: it waits\n"
                    "for Ctrl+C):\n\n```python\nprint(2)\n```\n\n```csv\na,b\n```\n")
    blocks = blocks_of(page)
    assert [(b.line, b.language, b.code, b.not_run) for b in blocks] == [
        (3, "bash", "echo one\n", None), (10, "python", "print(2)\n", "it waits for Ctrl+C"),
        (14, "csv", "a,b\n", None)]


def test_a_broken_example_fails(tmp_path: Path) -> None:
    """What the docs test sees when a page uses a column the corpus no longer has."""
    broken = Block(tmp_path / "page.md", 1, "python", "import pandas as pd\npd.DataFrame({'a': [1]})['tempo']\n", None)
    done = run_block(broken, tmp_path, reader_environment(tmp_path))
    assert done.returncode != 0 and "KeyError: 'tempo'" in done.stderr
    assert run_block(Block(broken.page, 1, "bash", "true\nfalse\necho after\n", None), tmp_path,
                     reader_environment(tmp_path)).returncode != 0  # bash stops at the first failure
