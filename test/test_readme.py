"""The README stays a front page: within its line budget, its links to the docs resolve."""
import os
import re

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
README_BUDGET = 260  # lines: what it is, two commands, install, tour, features, help


def test_readme_within_budget():
    with open(os.path.join(REPO, 'README.md'), encoding='utf-8') as f:
        lines = f.read().splitlines()
    assert len(lines) <= README_BUDGET, (
        f'README.md has {len(lines)} lines, its budget is {README_BUDGET}: move the detail '
        'to a page in docs/ and link it')


def test_readme_links_resolve():
    with open(os.path.join(REPO, 'README.md'), encoding='utf-8') as f:
        text = f.read()
    targets = re.findall(r'\]\(([^)#\s]+)(?:#[^)]*)?\)', text)
    local = [t for t in targets if '://' not in t and not t.startswith('mailto:')]
    missing = [t for t in local if not os.path.exists(os.path.join(REPO, t))]
    assert local and not missing, f'README links to missing files: {missing}'


