"""Every relative link in README.md and docs/*.md points at a file (or folder) inside the repository."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
FENCE = re.compile(r"^```.*?^```", flags=re.S | re.M)


def _documents() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def _relative_links(doc: Path) -> list[str]:
    text = FENCE.sub("", doc.read_text(encoding="utf-8"))  # code blocks hold commands, not links
    targets = [m.group(1).strip("<>") for m in LINK.finditer(text)]
    return [t for t in targets if not re.match(r"^[a-z][a-z0-9+.-]*:", t) and not t.startswith("#")]


def test_relative_links_resolve_inside_the_repository() -> None:
    broken = []
    for doc in _documents():
        for target in _relative_links(doc):
            path = (doc.parent / target.split("#", 1)[0]).resolve()
            if not path.is_relative_to(ROOT) or not path.exists():
                broken.append(f"{doc.relative_to(ROOT)}: {target}")
    assert not broken, broken


def test_the_check_sees_links_and_a_broken_one(tmp_path: Path) -> None:
    """The link finder finds the README's links, and a link leaving the repository counts as broken."""
    readme = _relative_links(ROOT / "README.md")
    assert "docs/architecture.md" in readme and "docs/standards.md" in readme
    doc = tmp_path / "x.md"
    doc.write_text("see [notes](../../elsewhere/notes.md) and [web](https://example.org)\n", encoding="utf-8")
    assert _relative_links(doc) == ["../../elsewhere/notes.md"]
    assert not (doc.parent / "../../elsewhere/notes.md").resolve().is_relative_to(ROOT)


def test_architecture_and_standards_live_in_docs() -> None:
    for name in ("architecture.md", "standards.md"):
        text = (ROOT / "docs" / name).read_text(encoding="utf-8")
        assert len(text) > 2000
    code = [p for p in ROOT.glob("*/**/*.py") if ".venv" not in p.parts]
    for path in code:
        text = path.read_text(encoding="utf-8")
        for m in re.finditer(r"\(([\w/]*standards\.md)", text):
            assert m.group(1) == "docs/standards.md", f"{path}: {m.group(0)}"
