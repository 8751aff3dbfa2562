"""The documentation against the tree and the built CLI (ctest ``docs.links``).

* README.md stays short (under 400 lines) and keeps the two commands that ``.ci/`` and the
  ctest ``main_job`` are described by;
* every relative link and image in README.md, resources/doc/*.md and tests/bench/README.md
  names an existing file (anchors are not checked);
* the images the README shows exist and are small (< 150 kB each);
* every file path in the "Thesis section → files" table of resources/doc/architecture.md
  exists, and every file the table names mentions the thesis reference of its row's
  chapter (its first comment is where the table came from);
* every ``parafab <subcommand>`` the README mentions is a subcommand of the built CLI
  (``parafab --help``).

Run with Debian's /usr/bin/python3. The CLI: ``$PARAFAB_CLI`` (set by ctest), else the first
argument's build folder (``test_docs.py BUILD_DIR``), else ``build/workbench/entry/parafab``;
without one the subcommand check is skipped.
"""

import os
import re
import subprocess
import sys
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, os.pardir, os.pardir))
README = os.path.join(REPO, "README.md")
DOC_DIR = os.path.join(REPO, "resources", "doc")
BENCH_README = os.path.join(REPO, "tests", "bench", "README.md")
ARCHITECTURE = os.path.join(DOC_DIR, "architecture.md")
MAX_README_LINES = 400
MAX_IMAGE_BYTES = 150 * 1024


def find_cli():
    cli = os.environ.get("PARAFAB_CLI")
    if not cli:
        build = sys.argv[1] if len(sys.argv) > 1 and not sys.argv[1].startswith("-") else os.path.join(REPO, "build")
        cli = os.path.join(build, "workbench", "entry", "parafab")
    return cli if os.path.isfile(cli) and os.access(cli, os.X_OK) else None


def documents():
    docs = [README, BENCH_README]
    docs += sorted(os.path.join(DOC_DIR, f) for f in os.listdir(DOC_DIR) if f.endswith(".md"))
    return docs


def read(path):
    with open(path, encoding="utf-8") as f:
        return f.read()


def prose(text):
    """``text`` without fenced code blocks and inline code spans (links there are not links)."""
    text = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
    return re.sub(r"`[^`\n]*`", "", text)


def code(text):
    """The fenced code blocks and inline code spans of ``text``, one string each."""
    blocks = re.findall(r"^```[^\n]*\n(.*?)^```", text, flags=re.S | re.M)
    rest = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
    return blocks + re.findall(r"`([^`\n]*)`", rest)


LINK = re.compile(r"!?\[(?:[^\]\[]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")


def links(text):
    """Targets of the Markdown links and images in ``text`` (inline form)."""
    return LINK.findall(prose(text))


def is_relative(target):
    return not re.match(r"^[a-z][a-z0-9+.-]*:", target, flags=re.I) and not target.startswith("#")


def subcommands_mentioned(text):
    """Words after ``parafab`` in the README's code: ``parafab strip``, ``.../parafab rod``."""
    found = set()
    for snippet in code(text):
        for line in snippet.splitlines():
            line = re.sub(r"(^|\s)#.*$", "", line)  # shell and Python comments are prose
            for m in re.finditer(r"(?:^|[\s/$(])parafab[ \t]+([a-z][a-z0-9-]*)\b", line):
                found.add(m.group(1))
    return found


def cli_subcommands(cli):
    """Subcommands listed by ``parafab --help`` (CLI11: the "Subcommands:" section)."""
    out = subprocess.run([cli, "--help"], capture_output=True, text=True, timeout=60)
    if out.returncode != 0:
        raise AssertionError("%s --help exited with %d: %s" % (cli, out.returncode, out.stderr))
    names, section = set(), False
    for line in out.stdout.splitlines():
        if re.match(r"^\s*Subcommands:\s*$", line, flags=re.I):
            section = True
            continue
        if section:
            m = re.match(r"^\s+([a-z][a-z0-9-]*)(\s|$)", line)
            if m:
                names.add(m.group(1))
            elif line.strip() and not line.startswith(" "):
                section = False
    return names


def architecture_table():
    """Rows of the "Thesis section → files" table: (thesis cell, [paths])."""
    text = read(ARCHITECTURE)
    m = re.search(r"^## Thesis section → files\n(.*?)(?=^## |\Z)", text, flags=re.S | re.M)
    if m is None:
        raise AssertionError("architecture.md has no '## Thesis section → files' section")
    rows = []
    for line in m.group(1).splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 3 or not line.lstrip().startswith("|") or set(cells[0]) <= set("-: "):
            continue
        if cells[0] == "thesis":
            continue
        rows.append((cells[0], re.findall(r"`([^`]+)`", cells[-1])))
    return rows


class ReadmeTest(unittest.TestCase):
    def test_short(self):
        n = len(read(README).splitlines())
        self.assertLess(n, MAX_README_LINES, "README.md has %d lines" % n)

    def test_two_commands_kept(self):
        # .ci/main.sh, .ci/test.sh, .ci/run and the ctest main_job are "the README's commands".
        text = read(README)
        for needle in ("## The two commands", "bash .ci/main.sh out", "bash .ci/test.sh",
                       "Command 1 writes the following into `out/`"):
            self.assertIn(needle, text)

    def test_images_small(self):
        images = [t for t in re.findall(r"!\[[^\]]*\]\(([^)\s]+)\)", prose(read(README))) if is_relative(t)]
        self.assertGreaterEqual(len(images), 4, images)
        for target in images:
            path = os.path.join(REPO, target.split("#")[0])
            self.assertTrue(os.path.isfile(path), target)
            self.assertLess(os.path.getsize(path), MAX_IMAGE_BYTES, "%s: %d bytes" % (target, os.path.getsize(path)))

    def test_subcommands_exist(self):
        cli = find_cli()
        if cli is None:
            self.skipTest("no built parafab CLI (PARAFAB_CLI or BUILD_DIR)")
        known = cli_subcommands(cli)
        self.assertIn("strip", known, "could not read the subcommands from %s --help" % cli)
        mentioned = subcommands_mentioned(read(README))
        self.assertTrue(mentioned, "README mentions no parafab subcommand")
        self.assertEqual(sorted(mentioned - known), [], "README mentions subcommands the CLI lacks; CLI has %s"
                         % sorted(known))


class LinkTest(unittest.TestCase):
    def test_relative_links_resolve(self):
        broken = []
        for doc in documents():
            for target in links(read(doc)):
                if not is_relative(target):
                    continue
                path = os.path.normpath(os.path.join(os.path.dirname(doc), target.split("#")[0]))
                if not os.path.exists(path):
                    broken.append("%s: %s" % (os.path.relpath(doc, REPO), target))
        self.assertEqual(broken, [])

    def test_link_parser(self):
        # The parser itself: links and images found, code ignored, anchors and URLs told apart.
        text = "a [x](b.md#c) ![i](img/p.png) `[no](not.md)`\n```\n[no](code.md)\n```\n[u](https://e.org) [h](#top)"
        self.assertEqual(links(text), ["b.md#c", "img/p.png", "https://e.org", "#top"])
        self.assertEqual([t for t in links(text) if is_relative(t)], ["b.md#c", "img/p.png"])
        self.assertEqual(subcommands_mentioned("`parafab rod x` and\n```sh\nbuild/x/parafab strip-improve y\n"
                                               "import parafab\nexport P=x  # the parafab module\n```\n"
                                               "the `parafab` module"),
                         {"rod", "strip-improve"})


class ArchitectureTest(unittest.TestCase):
    def test_table_paths_exist(self):
        rows = architecture_table()
        self.assertGreater(len(rows), 20)
        missing = [p for _, paths in rows for p in paths if not os.path.exists(os.path.join(REPO, p))]
        self.assertEqual(missing, [])
        self.assertTrue(all(paths for _, paths in rows), [r for r in rows if not r[1]])

    def test_table_matches_first_comments(self):
        # Each named file refers to the thesis chapter of its row (§4…, Eq. 5…, Theorem 1, …)
        # somewhere in its opening comment (the first 40 lines).
        wrong = []
        for thesis, paths in architecture_table():
            chapters = set(re.findall(r"(?:§|Eq\. |App\. )([0-9A-B])", thesis))
            if "Theorem" in thesis or "Algorithm" in thesis:
                chapters.add("4")
            for p in paths:
                with open(os.path.join(REPO, p), encoding="utf-8") as f:
                    head = "".join(f.readline() for _ in range(40))
                refs = set(re.findall(r"(?:§ ?|Eqs?\. ?|Appendix |App\. )([0-9A-B])", head))
                if "Theorem 1" in head or "Algorithm 4" in head:
                    refs.add("4")
                if not chapters & refs:
                    wrong.append("%s (row %s): first comment cites %s" % (p, thesis, sorted(refs)))
        self.assertEqual(wrong, [])


if __name__ == "__main__":
    unittest.main(argv=[sys.argv[0]] + [a for a in sys.argv[1:] if a.startswith("-")])
