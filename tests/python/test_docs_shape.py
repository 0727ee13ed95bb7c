"""The docs as a reader meets them (issue 57): every link to a section of README.md or docs/*.md
lands on a heading that exists (a section moved to another page takes its links along), and
docs/BENCHMARKS.md's headline keeps to the figures a user chooses by (at most 15 rows, each on a
machine its key defines)."""

import pathlib
import re

ROOT = pathlib.Path(__file__).resolve().parents[2]
PAGES = sorted(ROOT.glob("docs/*.md")) + [ROOT / "README.md"]


def slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation other than '-' and '_' dropped, spaces as '-'."""
    return re.sub(r"[^a-z0-9 _-]", "", heading.strip().lower()).replace(" ", "-")


def anchors(page: pathlib.Path) -> set:
    return {slug(m.group(1)) for m in re.finditer(r"^#+ (.*)$", page.read_text(), re.M)}


def test_slug_follows_githubs_rule():
    # Independent examples, the anchors GitHub gives these headings.
    assert slug("Warm starts (`hbrdf fit --init MODEL|prior`)") == "warm-starts-hbrdf-fit---init-modelprior"
    assert slug("`hbrdf add`'s loss epsilon: 0.03 (`ADD_LOSS_EPS`)") == "hbrdf-adds-loss-epsilon-003-add_loss_eps"


def test_every_section_link_lands_on_a_heading():
    known = {page.resolve(): anchors(page) for page in PAGES}
    broken = []
    for page in PAGES:
        for m in re.finditer(r"\]\(([\w./-]*\.md)?#([\w-]+)\)", page.read_text()):
            target = (page.parent / m.group(1)).resolve() if m.group(1) else page.resolve()
            if target in known and m.group(2) not in known[target]:
                broken.append(f"{page.relative_to(ROOT)}: {m.group(0)}")
    assert not broken, "links to headings that do not exist:\n" + "\n".join(broken)


def test_benchmarks_headline_has_at_most_15_rows_on_defined_machines():
    text = (ROOT / "docs" / "BENCHMARKS.md").read_text()
    headline = text.split("## Headline", 1)[1].split("\n## ", 1)[0]
    table, key = headline.split("Machines (each key", 1)
    rows = [ln for ln in table.splitlines() if ln.startswith("| ") and not ln.startswith("| figure")]
    assert 5 <= len(rows) <= 15, len(rows)
    defined = set(re.findall(r"^- \*\*(\w+)\*\* =", key, re.M))
    for row in rows:
        machines = {m.strip().split(" ")[0] for m in row.split(" | ")[-2].split(",")}
        assert machines <= defined, (row[:80], machines - defined)


def test_no_page_over_600_lines():
    # A newcomer's path (README -> ARCHITECTURE -> the page of their task) stays readable; history
    # goes to BENCHMARKS_HISTORY.md or the topic's own page.
    long = {p.name: n for p in PAGES if (n := len(p.read_text().splitlines())) > 600}
    assert not long, long
