"""The documentation's own links resolve: every relative link in README.md and docs/*.md names a file that exists,
and every ``file.md#anchor`` a heading of that file (GitHub's slugs). The measured numbers live in
docs/performance.md alone and the other docs link into it, so a renamed heading must not leave dead links."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
_LINK = re.compile(r"\]\(([^)\s]*?)(?:#([^)\s]+))?\)")


def heading_slugs(path: Path) -> set[str]:
    """GitHub's anchors of a markdown file's headings (lower case, punctuation dropped, spaces to '-', -1, -2
    for repeats); headings inside fenced code do not count."""
    out: set[str] = set()
    seen: dict[str, int] = {}
    in_code = False
    for line in path.read_text().splitlines():
        if line.startswith("```"):
            in_code = not in_code
        if in_code or not re.match(r"#{1,6} ", line):
            continue
        slug = re.sub(r"[^\w\- ]", "", line.lstrip("#").strip().lower()).replace(" ", "-")
        count = seen.get(slug, 0)
        seen[slug] = count + 1
        out.add(slug if count == 0 else f"{slug}-{count}")
    return out


def dead_links() -> list[str]:
    bad = []
    for doc in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        for match in _LINK.finditer(doc.read_text()):
            target, anchor = match.group(1), match.group(2)
            if target.startswith(("http", "mailto")) or not (target or anchor):
                continue
            path = (doc.parent / target) if target else doc
            if not path.exists():
                bad.append(f"{doc.name}: no file {target}")
            elif anchor and path.suffix == ".md" and anchor not in heading_slugs(path):
                bad.append(f"{doc.name}: no heading #{anchor} in {path.name}")
    return bad


def test_every_relative_link_in_the_docs_resolves() -> None:
    assert not dead_links()


def test_the_anchor_rule_follows_github(tmp_path: Path) -> None:
    doc = tmp_path / "d.md"
    doc.write_text(
        "# Traffic encounters\n## Lockstep: per-step (µs)\n```\n# not a heading\n```\n## Routing\n## Routing\n"
    )
    assert heading_slugs(doc) == {"traffic-encounters", "lockstep-per-step-µs", "routing", "routing-1"}
