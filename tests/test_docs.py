"""The documentation's references resolve and its figures have one source:
README.md is the front door (under 300 lines) and links every guide and
design note in docs/; every link between README.md and docs/*.md names an
existing file and, with #anchor, one of its headings; the documents named in
the host package exist; and every number in README.md's goals table is in
bench/RESULTS.md, the file `make bench` writes."""
import re
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
README = REPO / "README.md"
DOCS = sorted((REPO / "docs").glob("*.md"))
sys.path.insert(0, str(REPO / "bench"))
import goals_table  # noqa: E402


def _slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces -> '-'."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def _anchors(path: Path) -> set:
    """Anchors of a markdown file's headings (not of '#' lines in code fences)."""
    out, fence = set(), False
    for line in path.read_text().splitlines():
        if line.startswith("```"):
            fence = not fence
        elif not fence and re.match(r"^#+ ", line):
            out.add(_slug(line.lstrip("#")))
    return out


def _links(path: Path) -> list:
    """(target file, anchor or None) of every relative markdown link in a file."""
    out = []
    for target in re.findall(r"\]\(([^)\s]+)\)", path.read_text()):
        if re.match(r"^[a-z]+:", target):
            continue                                    # http:, mailto: ...
        file, _, anchor = target.partition("#")
        out.append(((path.parent / file).resolve() if file else path, anchor or None))
    return out


def test_readme_is_a_front_door():
    lines = README.read_text().splitlines()
    assert len(lines) < 300, len(lines)


def test_readme_links_every_doc():
    linked = {f for f, _ in _links(README)}
    missing = [d.name for d in DOCS if d.resolve() not in linked]
    assert not missing, missing


def test_links_resolve():
    bad = []
    for doc in [README] + DOCS:
        for file, anchor in _links(doc):
            if not file.exists():
                bad.append((doc.name, str(file), anchor))
            elif anchor and file.suffix == ".md" and anchor not in _anchors(file):
                bad.append((doc.name, file.name, anchor))
    assert not bad, bad


def test_readme_links_docs():
    """The README reaches the guides and design notes through docs/*.md links."""
    docs_links = re.findall(r"\]\((docs/[\w./-]+\.md)(?:#[^)]*)?\)", README.read_text())
    assert len(set(docs_links)) >= 12, sorted(set(docs_links))


def test_documents_named_exist():
    files = [README] + DOCS + sorted((REPO / "host" / "motecal").rglob("*.py"))
    missing = [(f.relative_to(REPO), ref) for f in files
               for ref in re.findall(r"docs/[\w./-]+\.md", f.read_text())
               if not (REPO / ref).is_file()]
    assert not missing, missing


def _goals_table(text: str) -> str:
    begin, end = text.index(goals_table.BEGIN), text.index(goals_table.END)
    return text[begin + len(goals_table.BEGIN):end]


def test_goals_table_numbers_are_in_results():
    table = _goals_table(README.read_text())
    results = (REPO / "bench" / "RESULTS.md").read_text()
    numbers = re.findall(r"-?\d+(?:\.\d+)?(?:e[+-]?\d+)?", table)
    assert len(numbers) > 20, numbers                  # the table is there and has figures
    assert not [n for n in numbers if n not in results]
    for row in table.splitlines():                    # and every goal row says met or not
        if row.startswith("| ") and "(#" in row:
            assert re.search(r"\| (met|\*\*not met\*\*|not measured) \|", row), row


def test_goals_table_is_generated_from_results():
    readme = README.read_text()
    block = goals_table.goals_block((REPO / "bench" / "RESULTS.md").read_text())
    assert goals_table.updated_readme(readme, block) == readme


def test_goals_table_check_catches_a_changed_figure(tmp_path):
    """The number check can fail: a figure that is not in RESULTS.md is found."""
    results = (REPO / "bench" / "RESULTS.md").read_text()
    table = _goals_table(README.read_text())
    m = re.search(r"\| (\d+(?:\.\d+)?) ", table)
    assert m
    changed = table.replace(m.group(0), "| 987654.321 ", 1)
    numbers = re.findall(r"-?\d+(?:\.\d+)?(?:e[+-]?\d+)?", changed)
    assert [n for n in numbers if n not in results] == ["987654.321"]
