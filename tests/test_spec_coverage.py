"""docs/spec-coverage.md, the table of what vrshark checks of TS-0006,
TS-0007 and SP-14-023, cannot rot: every test it names exists (file and
function), every field, expert field or preference it names is registered,
every file it names exists, and every row has one of the four statuses."""
import ast
import re

from conftest import ROOT
# fields and expert fields (tshark -G fields), preferences (-G defaultprefs)
from test_docs import PROTOCOLS, preferences, registered  # noqa: F401 (fixtures)

PAGE = ROOT / "docs" / "spec-coverage.md"
NAME = re.compile(r"^(%s|eclink_\*)(\.[a-z0-9_]+)+$" % "|".join(PROTOCOLS))
TEST = re.compile(r"^(tests/test_[a-z0-9_]+\.py)::(test_[a-z0-9_]+)$")
FILE = re.compile(r"^(lua|plugins|tools|tests)/[A-Za-z0-9_./-]+$")
STATUS = re.compile(r"^(checked|partial|not checked)\b")
SPECS = {"TS-0006 EG-Link over UDP": "E", "TS-0007 EC-Link": "C", "SP-14-023 MC-MB2-PN": "M"}


def rows():
    """(spec, cells) of every table row of the page, by column name."""
    out = []
    spec = None
    header = None
    for line in PAGE.read_text().splitlines():
        if line.startswith("## "):
            spec, header = line[3:].strip(), None
        elif line.startswith("|") and spec:
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if header is None:
                header = cells
            elif not set(cells[0]) <= set("-"):
                out.append((spec, dict(zip(header, cells))))
    return out


ROWS = rows()


def names(cell):
    return re.findall(r"`([^`]+)`", cell)


def test_the_page_has_the_three_specs_and_its_columns():
    assert {spec for spec, _ in ROWS} == set(SPECS)
    for spec, row in ROWS:
        assert list(row) == ["#", "statement", "section", "decoded / checked in", "test", "status"], row
        assert row["#"].startswith(SPECS[spec]), row["#"]
        assert re.match(r"^\d+(\.\d+)*", row["section"]), row
    numbers = [row["#"] for _, row in ROWS]
    assert len(numbers) == len(set(numbers)), "row numbers repeat"
    # thorough: the three specs read section by section
    assert sum(1 for spec, _ in ROWS if spec.startswith("TS-0006")) >= 40
    assert sum(1 for spec, _ in ROWS if spec.startswith("TS-0007")) >= 40
    assert sum(1 for spec, _ in ROWS if spec.startswith("SP-14-023")) >= 25


def test_every_status_is_one_of_four_and_says_why():
    for _, row in ROWS:
        status = row["status"]
        assert STATUS.match(status), row
        if status.startswith(("partial", "not checked")):
            # the why
            assert ":" in status, row
        if status.startswith("checked"):
            assert names(row["test"]) and names(row["decoded / checked in"]), row


def test_every_named_test_exists():
    defined = {}
    for _, row in ROWS:
        for ref in names(row["test"]):
            m = TEST.match(ref)
            assert m, "not a test reference: %r (row %s)" % (ref, row["#"])
            path = ROOT / m.group(1)
            assert path.exists(), ref
            if path not in defined:
                tree = ast.parse(path.read_text())
                defined[path] = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
            assert m.group(2) in defined[path], "%s: no such test function" % ref


def test_every_named_field_expert_and_file_exists(registered, preferences):  # noqa: F811 (the fixtures)
    """Every backticked name in the "decoded / checked in" column: a file of
    the project or a registered name (eclink_* stands for both EC-Link
    transports)."""
    unknown = []
    for _, row in ROWS:
        for ref in names(row["decoded / checked in"]):
            if FILE.match(ref):
                if not (ROOT / ref).exists():
                    unknown.append((row["#"], ref))
                continue
            assert NAME.match(ref), "neither a file nor a filter name: %r (row %s)" % (ref, row["#"])
            for name in ([ref.replace("*", t) for t in ("modbus", "pnio")] if "*" in ref else [ref]):
                if name not in registered and name not in preferences:
                    unknown.append((row["#"], name))
    assert not unknown, unknown


def test_linked_from_the_readme_and_the_docs():
    assert "(docs/spec-coverage.md)" in (ROOT / "README.md").read_text()
