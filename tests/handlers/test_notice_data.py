"""The copied notices are the unedited files that SOURCES.md describes."""

import hashlib
import re

from notice_helpers import NOTICES


def test_every_notice_is_listed_with_its_sha256_prefix():
    text = (NOTICES / "SOURCES.md").read_text()
    listed = dict(re.findall(r"^\| `([^`]+)` \| ([0-9a-f]{16}) \|", text, flags=re.M))
    files = sorted(p.relative_to(NOTICES).as_posix() for p in NOTICES.rglob("*") if p.is_file()
                   and p.name != "SOURCES.md")
    assert sorted(listed) == files
    for rel, prefix in listed.items():
        assert hashlib.sha256((NOTICES / rel).read_bytes()).hexdigest()[:16] == prefix, rel
