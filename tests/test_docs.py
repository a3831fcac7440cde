"""The documentation's references resolve: documents named in README.md and in
the host package exist (docs/readme/*.md were merged into README.md),
and every in-page link of README.md names one of its headings."""
import re
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def _slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces -> '-'."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def test_documents_named_exist():
    files = [REPO / "README.md"] + sorted((REPO / "host" / "motecal").rglob("*.py"))
    missing = [(f.relative_to(REPO), ref) for f in files
               for ref in re.findall(r"docs/[\w./-]+\.md", f.read_text())
               if not (REPO / ref).is_file()]
    assert not missing, missing


def test_readme_links_name_its_headings():
    text = (REPO / "README.md").read_text()
    anchors = {_slug(h) for h in re.findall(r"^#+ (.+)$", text, re.M)}
    links = re.findall(r"\]\(#([^)]+)\)", text)
    assert links and not [a for a in links if a not in anchors]
