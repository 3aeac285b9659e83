"""The seam between the C plugin and the Lua plugins as one contract: the
names and limits of plugins/vrshark/vrshark-frontends.h (VRSHARK_NAME) and of
lua/vrshark/seam.luam (NAME) are the same, no source spells one as a literal
instead, a mistyped name or hook key is an error, and the view the C front
ends put into pinfo.match_string reads back as it was written.

seam.luam is plain Lua: it is run by each Lua interpreter installed
(lua5.4, lua5.2: tools/setup) and by tshark's own (-X lua_script)."""
import re
import shutil
import subprocess
from itertools import combinations

import pytest

from conftest import CAPTURES, ROOT, _world_dir
from seam_testlib import CONTRACT

SEAM = ROOT / "lua" / "vrshark" / "seam.luam"
C_SOURCES = sorted((ROOT / "plugins" / "vrshark").glob("*.c"))
LUA_SOURCES = sorted(p for p in (ROOT / "lua").rglob("*") if p.suffix in (".lua", ".luam") and p != SEAM)
SEAM_FUNCTIONS = {"view", "key", "server_key"}
STRINGS = {name: value for name, value in CONTRACT.items() if isinstance(value, str)}


def view_cases():
    """(match_string or None, expected decoding) as the C front ends write
    them (vrshark-frontends.c:lua_view): hook, hook .quiet, hook
    .sparse:FLAGS:LIST with FLAGS in the order c, e, p; the malformed frame;
    the keys of string-table calls; none."""
    c = CONTRACT
    flags = [("cols", c["VIEW_FLAG_COLS"]), ("experts", c["VIEW_FLAG_EXPERTS"]), ("protos", c["VIEW_FLAG_PROTOS"])]
    lists = [[], ["mcmb2.uplink.terminal"], ["eclink.pci", "eclink_modbus.adu_kind", "vrshark_io.mcmb2.up.x-1"]]
    cases = [(None, {"hook": False, "malformed": False, "view": None})]
    for hook in (c["VIEW_FRAME_ID"], c["MB_HOOK_HEURISTIC"], c["MB_HOOK_ALWAYS"], c["MB_HOOK_SERVER"]):
        cases.append((hook, {"hook": hook, "malformed": False, "view": None}))
        cases.append((hook + c["VIEW_QUIET"], {"hook": hook, "malformed": False, "view": "quiet"}))
        for n in range(4):
            for on in combinations(flags, n):
                for fields in lists:
                    text = hook + c["VIEW_SPARSE"] + "".join(f for _, f in on) + ":" + c["VIEW_LIST_SEP"].join(fields)
                    want = {k: any(k == name for name, _ in on) for k, _ in flags}
                    want["fields"] = sorted(fields)
                    cases.append((text, {"hook": hook, "malformed": False, "view": want}))
    cases.append((c["VIEW_MALFORMED"], {"hook": c["VIEW_FRAME_ID"], "malformed": True, "view": None}))
    for key in (c["PN_HOOK_CONNECT"], c["PN_HOOK_CANDIDATE"], c["MB_HOOK_PORT_HINT"]):
        cases.append((key, {"hook": key, "malformed": False, "view": None}))
    return cases


CASES = view_cases()


def lua_string(text):
    return "nil" if text is None else '"%s"' % text.replace("\\", "\\\\").replace('"', '\\"')


def probe_script():
    """A Lua script that writes, one a line, the module's constants, each
    case's decoding, and what a mistyped name or key does."""
    views = ",\n".join("{ %s }" % lua_string(how) for how, _ in CASES)
    return r"""
package.path = "%(lua)s/?.luam;" .. package.path
local seam = require("vrshark.seam")
local out = assert(io.open("%(out)s", "w"))
for k, v in pairs(seam) do
    if type(v) ~= "function" then out:write("const\t", k, "\t", type(v), "\t", tostring(v), "\n") end
end
local cases = { """ + views + r""" }
local function flag(b) return b and "1" or "0" end
local function decode(i, how)
    local d = seam.view(how)
    local v, kind = d.view, "nil"
    if v and v.quiet then kind = "quiet"
    elseif v then
        local names = {}
        for name in pairs(v.fields) do names[#names + 1] = name end
        table.sort(names)
        kind = flag(v.cols) .. flag(v.experts) .. flag(v.protos) .. "\t" .. table.concat(names, " ")
            .. "\t" .. type(v.plans)
    end
    out:write("view\t", i, "\t", tostring(d.hook), "\t", tostring(d.malformed), "\t", kind, "\n")
end
for i, c in ipairs(cases) do decode(i, c[1]) end
-- (cached: the same string, the same table; still right once the cache was emptied)
out:write("same\t", tostring(seam.view(cases[#cases][1]) == seam.view(cases[#cases][1])), "\n")
for n = 1, 300 do seam.view("frame_id.sparse:c:f" .. n) end
for i, c in ipairs(cases) do decode(i, c[1]) end
local function try(what, f, ...)
    local ok, err = pcall(f, ...)
    out:write("try\t", what, "\t", tostring(ok), "\t", tostring(err):gsub("\n", " "), "\n")
end
try("mistyped_name", function() return seam.PN_HOOK_PENDNG end)
try("set_name", function() seam.FLAG_PN_PENDING = "x" end)
try("mistyped_key", seam.key, seam.PN_HOOK_TABLE, "pendng")
try("other_tables_key", seam.key, seam.PN_HOOK_TABLE, seam.MB_HOOK_ALWAYS)
try("server_key_pn", seam.key, seam.PN_HOOK_TABLE, seam.server_key("10.0.0.1", 502))
try("no_table", seam.key, "vrshark.pn.hooks", seam.FLAG_PN_PENDING)
try("pending", seam.key, seam.PN_HOOK_TABLE, seam.FLAG_PN_PENDING)
try("mistyped_flag", seam.key, seam.PN_HOOK_TABLE, "pn.pendng")
try("flag_in_mb", seam.key, seam.MB_HOOK_TABLE, seam.FLAG_PN_RESPONSE)
try("port_hint", seam.key, seam.MB_HOOK_TABLE, seam.MB_HOOK_PORT_HINT)
try("server_key", seam.key, seam.MB_HOOK_TABLE, seam.server_key("10.0.0.1", 502))
try("server_key_any_port", seam.key, seam.MB_HOOK_TABLE, seam.server_key("10.0.0.1"))
out:close()
"""


INTERPRETERS = ["tshark"] + [name for name in ("lua5.4", "lua5.2") if shutil.which(name)]


@pytest.fixture(scope="module", params=INTERPRETERS)
def probed(request, tshark):
    """The probe's lines, by kind: {"const": {name: value}, "view": [...], "same": ..., "try": {...}}."""
    # (a folder tshark can write in when tools/tshark drops root)
    work = _world_dir("vrshark-seam-")
    request.addfinalizer(lambda: shutil.rmtree(work, ignore_errors=True))
    out = work / "probe.txt"
    out.touch()
    out.chmod(0o666)
    script = work / "probe.lua"
    script.write_text(probe_script() % {"lua": ROOT / "lua", "out": out})
    script.chmod(0o644)
    if request.param == "tshark":
        cmd = [tshark.cmd, "-n", "-q", "-r", str(CAPTURES / "eclink_pnio_connect.pcap"), "-c", "1",
               "-X", "lua_script:%s" % script]
        env = tshark.env
    else:
        cmd, env = [request.param, str(script)], None
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "Lua Error" not in proc.stdout + proc.stderr
    got = {"const": {}, "view": [], "try": {}}
    for line in out.read_text().splitlines():
        kind, *rest = line.split("\t")
        if kind == "const":
            name, typ, value = rest
            got["const"][name] = int(value) if typ == "number" else value
        elif kind == "view":
            got["view"].append(rest)
        elif kind == "same":
            got["same"] = rest[0]
        else:
            got["try"][rest[0]] = (rest[1] == "true", rest[2])
    return got


def expected_row(i, want):
    v = want["view"]
    if v is None:
        kind = ["nil"]
    elif v == "quiet":
        kind = ["quiet"]
    else:
        kind = ["".join("1" if v[k] else "0" for k in ("cols", "experts", "protos")), " ".join(v["fields"]), "table"]
    return [str(i), str(want["hook"]).lower() if want["hook"] is False else want["hook"],
            str(want["malformed"]).lower()] + kind


def test_both_sides_name_the_same(probed):
    # (Lua's numbers may print as 64 or 64.0: compared as numbers)
    got = {k: (int(float(v)) if k.endswith("_TRIES") else v) for k, v in probed["const"].items()}
    assert got == CONTRACT
    assert {"PN_HOOK_TABLE", "MB_HOOK_TABLE", "FLAG_PN_PENDING", "FLAG_PN_RESPONSE", "FN_FLAG", "FN_SERVERS",
            "FN_MB_HOOKS_CHANGED", "MB_HOOK_PORT_HINT", "VIEW_MALFORMED",
            "ENV_FULL_TREE", "PN_CANDIDATE_TRIES", "MB_CANDIDATE_TRIES"} <= set(CONTRACT)


def test_the_view_reads_back_as_written(probed):
    want = [expected_row(i, w) for i, (_, w) in enumerate(CASES, 1)]
    assert probed["view"] == want + want
    assert probed["same"] == "true"


def test_a_mistyped_name_or_key_is_an_error(probed):
    t = probed["try"]
    for what, needle in (("mistyped_name", "no PN_HOOK_PENDNG"), ("set_name", "FLAG_PN_PENDING is not to be set"),
                         ("mistyped_key", "no hook pendng in vrshark.pn.hook"),
                         ("mistyped_flag", "no hook pn.pendng in vrshark.pn.hook"),
                         ("flag_in_mb", "no hook pn.response in vrshark.mbtcp.hook"),
                         ("other_tables_key", "no hook always in vrshark.pn.hook"),
                         ("server_key_pn", "no hook server 10.0.0.1:502 in vrshark.pn.hook"),
                         ("no_table", "no hook table vrshark.pn.hooks")):
        ok, err = t[what]
        assert not ok and needle in err, (what, err)
    assert t["pending"] == (True, "pn.pending")
    assert t["port_hint"] == (True, "port_hint")
    assert t["server_key"] == (True, "server 10.0.0.1:502")
    assert t["server_key_any_port"] == (True, "server 10.0.0.1")


def code_of_c(text):
    """C text without its comments (string literals kept; lines where they
    were, so that a finding names its line)."""
    return re.sub(r'/\*.*?\*/|//[^\n]*', lambda m: " " + "\n" * m.group(0).count("\n"), text, flags=re.S)


def code_of_lua(text):
    """Lua text without its comments (string literals kept; long strings are
    not used in these sources)."""
    out, i, n = [], 0, len(text)
    while i < n:
        ch = text[i]
        if ch in "\"'":
            j = i + 1
            while j < n and text[j] != ch:
                j += 2 if text[j] == "\\" else 1
            out.append(text[i:j + 1])
            i = j + 1
        elif text.startswith("--", i):
            if text.startswith("--[[", i):
                end = text.find("]]", i) + 2
                out.append("\n" * text.count("\n", i, end))
                i = end
            else:
                i = text.find("\n", i)
                i = n if i < 0 else i
        else:
            out.append(ch)
            i += 1
    return "".join(out)


# Contract strings that name nothing else in these sources: a literal of one
# anywhere is the contract spelt out by hand. The hook names (words such as
# "candidate", also a record kind, or "frame_id", a column of an IO list) and
# the one-letter flags are caught where they are used as hook keys or views
# (HOOK_USES).
WORDS = {v for k, v in STRINGS.items() if "_HOOK_" in k or k == "VIEW_FRAME_ID" or len(v) == 1}
DISTINCT = set(STRINGS.values()) - WORDS
LITERAL = re.compile(r'"((?:[^"\\\n]|\\.)*)"')
HOOK_USES = [
    # C: a string table looked up or called with a literal key
    re.compile(r'dissector_(?:get|try)_string\w*\(\s*\w+\s*,\s*"'),
    # Lua: a hook table's entry added or removed, fe.hook, a view compared
    re.compile(r'(?:_hook|hook_table)\s*:\s*(?:add|remove)\s*\(\s*"'),
    re.compile(r'\bhook\s*\(\s*[\w.]+\s*,\s*"'),
    re.compile(r'\b(?:how|match_string|hook)\s*[=~]=\s*"'),
    re.compile(r'\bDissector(?:Table)?\.(?:get|new)\s*\(\s*"vrshark\.'),
]


def literal_uses(path):
    text = path.read_text()
    code = code_of_c(text) if path.suffix == ".c" else code_of_lua(text)
    found = []
    for n, line in enumerate(code.splitlines(), 1):
        if any(m.group(1) in DISTINCT for m in LITERAL.finditer(line)) or any(p.search(line) for p in HOOK_USES):
            found.append((path.name, n, line.strip()))
    return found


def test_no_source_spells_the_contract_out():
    found = [use for path in C_SOURCES + LUA_SOURCES for use in literal_uses(path)]
    assert found == []


def test_the_check_catches_a_mistyped_key(tmp_path):
    """The static check fails on the mistakes it is there for."""
    lua = tmp_path / "bad.lua"
    lua.write_text('local x = 1 -- fe.hook(fe.pn_hook, "pending", p, true) in a comment is fine\n'
                   'fe.hook(fe.pn_hook, "pendng", carrier, true)\n'
                   'fe.mb_hook:add("port_hint", proto)\n'
                   'if how == "connect" then end\n'
                   'local t = DissectorTable.get("vrshark.pn.hook")\n')
    c = tmp_path / "bad.c"
    c.write_text('/* "port_hint" */ x = dissector_get_string_handle(pn_hook_table, "pendng");\n')
    assert [n for _, n, _ in literal_uses(lua)] == [2, 3, 4, 5]
    assert [n for _, n, _ in literal_uses(c)] == [1]


def test_every_seam_name_used_is_defined():
    used = set()
    for path in LUA_SOURCES:
        code = code_of_lua(path.read_text())
        used |= set(re.findall(r'\bseam\.([A-Za-z_]\w*)', code))
        used |= set(re.findall(r'require\("vrshark\.seam"\)\.([A-Za-z_]\w*)', code))
    assert used, "no Lua source reads vrshark.seam"
    assert used - set(CONTRACT) - SEAM_FUNCTIONS == set()


def test_the_column_writers_named_are_exported():
    text = (ROOT / "plugins" / "vrshark" / "vrshark-columns.c").read_text()
    for name in ("FN_SET_COLS", "FN_APPEND_INFO", "FN_CLOCK_DUE", "FN_CLOCK_MARK"):
        assert re.search(r"VRSHARK_EXPORT int %s\(lua_State \*L\);" % CONTRACT[name], text), name


def test_the_state_functions_named_are_exported():
    text = (ROOT / "plugins" / "vrshark" / "vrshark-flags.c").read_text()
    for name in ("FN_FLAG", "FN_SERVERS", "FN_MB_HOOKS_CHANGED"):
        assert re.search(r"VRSHARK_EXPORT int %s\(lua_State \*L\);" % CONTRACT[name], text), name


# The contract's own families of names in C: one not #defined by the header
# is a mistyped name (a literal in its place is caught by literal_uses).
C_NAME = re.compile(r"\bVRSHARK_((?:PN|MB|VIEW|ENV|FN|FLAG)_\w+)")
C_FILES = sorted((ROOT / "plugins" / "vrshark").glob("*.[ch]"))


def undefined_names(path):
    """(file, line, name) of each contract-family name the C code uses that
    the contract does not define."""
    code = code_of_c(path.read_text())
    return [(path.name, n, m.group(0)) for n, line in enumerate(code.splitlines(), 1)
            for m in C_NAME.finditer(line) if m.group(1) not in CONTRACT]


def test_c_uses_only_names_the_contract_defines():
    assert [u for path in C_FILES for u in undefined_names(path)] == []


# Where a Lua source takes a hook key or a flag into a local to hand it to
# fe.hook: `local A, B = seam.X, seam.Y` (over lines; a literal among them
# binds its name to nothing).
SEAM_VALUE = r'(?:seam\.\w+|"[^"\n]*")'
SEAM_LOCALS = re.compile(r"\blocal\s+([\w\s,]+?)\s*=\s*(%s(?:\s*,\s*%s)*)" % (SEAM_VALUE, SEAM_VALUE))
FE_HOOK_KEY = re.compile(r"\bfe\.hook\s*\(\s*[\w.]+\s*,\s*([^,]+?)\s*,")


def hook_key_uses(path):
    """(file, line, key) of each fe.hook call whose key is not a local bound
    to a hook or flag name of the contract."""
    code = code_of_lua(path.read_text())
    bound = {}
    for names, values in SEAM_LOCALS.findall(code):
        for name, value in zip(re.split(r"\s*,\s*", names.strip()), re.split(r"\s*,\s*", values.strip())):
            bound[name] = value[len("seam."):]
    found = []
    for n, line in enumerate(code.splitlines(), 1):
        for m in FE_HOOK_KEY.finditer(line):
            name = bound.get(m.group(1))
            if not (name in CONTRACT and ("_HOOK_" in name or name.startswith("FLAG_"))):
                found.append((path.name, n, m.group(1)))
    return found


def test_every_hook_key_handed_over_is_a_contract_name():
    assert [u for path in LUA_SOURCES for u in hook_key_uses(path)] == []


# Only frontends.luam touches the hook tables and the C functions: what a
# decoder puts into them goes through its hook(), which checks the key
# (seam.key) and sends a flag or a listed server to C.
ONLY_FRONTENDS = re.compile(r"\bseam\.(?:PN_HOOK_TABLE|MB_HOOK_TABLE|FN_\w+)\b|\bpackage\.loadlib\b")


def test_only_frontends_touches_the_hook_tables():
    found = [(path.name, n, line.strip()) for path in LUA_SOURCES if path.name != "frontends.luam"
             for n, line in enumerate(code_of_lua(path.read_text()).splitlines(), 1) if ONLY_FRONTENDS.search(line)]
    assert found == []


# Mistakes put into copies of the real sources, and what catches each.
MISTAKES = [
    # (source, the text replaced, its replacement, the check, what it reports)
    ("lua/vrshark/transport.luam", "seam.FLAG_PN_PENDING", '"pn.pendng"', hook_key_uses, "FLAG_PENDING"),
    ("lua/vrshark/transport.luam", "fe.hook(hook_table, HOOK_CONNECT,", 'fe.hook(hook_table, "conect",', literal_uses,
     'fe.hook(hook_table, "conect", proto, connect)'),
    ("lua/vrshark/transport.luam", "fe.hook(fe.mb_hook, HOOK_ALWAYS,", 'fe.hook(fe.mb_hook, "always",', literal_uses,
     'fe.hook(fe.mb_hook, "always", proto, always)'),
    ("plugins/vrshark/vrshark-frontends.c", "VRSHARK_PN_HOOK_CONNECT, tvb", '"connect", tvb', literal_uses,
     'dissector_try_string_with_data(pn_hook_table, "connect", tvb'),
    ("plugins/vrshark/vrshark-frontends.c", "VRSHARK_PN_HOOK_CLOCK)))", "VRSHARK_PN_HOOK_CLOK)))", undefined_names,
     "VRSHARK_PN_HOOK_CLOK"),
    ("plugins/vrshark/vrshark-flags.c", "VRSHARK_FLAG_PN_RESPONSE)", '"pn.response")', literal_uses,
     'strcmp(name, "pn.response")'),
    ("plugins/vrshark/vrshark-flags.c", "VRSHARK_FLAG_PN_RESPONSE)", "VRSHARK_FLAG_PN_RESPONS)", undefined_names,
     "VRSHARK_FLAG_PN_RESPONS"),
]


@pytest.mark.parametrize("source,old,new,check,reported", MISTAKES, ids=[
    "lua-flag-local", "lua-hook-literal", "lua-mb-hook-literal", "c-hook-literal", "c-undefined-hook",
    "c-flag-literal", "c-undefined-flag"])
def test_a_mistake_in_a_real_source_is_caught(tmp_path, source, old, new, check, reported):
    real = ROOT / source
    text = real.read_text()
    assert old in text, "the source changed: pick another place for the mistake"
    assert check(real) == []
    bad = tmp_path / real.name
    bad.write_text(text.replace(old, new, 1))
    found = check(bad)
    assert len(found) == 1 and reported in found[0][2], found


# A BU's evidence: the addresses of its images (tests/test_modbus_evidence.py
# feeds both sides the requests at and around each bound).
EVIDENCE = {"MB_INPUT_REG_FIRST", "MB_INPUT_HOLDING_FIRST", "MB_INPUT_REGS", "MB_INPUT_BIT_FIRST", "MB_INPUT_BITS",
            "MB_OUTPUT_REG_FIRST", "MB_OUTPUT_REGS", "MB_OUTPUT_COMMANDS_REGS", "MB_OUTPUT_COIL_FIRST"}


def evidence_numbers():
    """The addresses and counts of the evidence, and the bounds made of them."""
    c = CONTRACT
    found = set()
    for first, n in (("MB_INPUT_REG_FIRST", "MB_INPUT_REGS"), ("MB_INPUT_HOLDING_FIRST", "MB_INPUT_REGS"),
                     ("MB_INPUT_BIT_FIRST", "MB_INPUT_BITS"), ("MB_OUTPUT_REG_FIRST", "MB_OUTPUT_REGS")):
        found |= {c[first], c[n], c[first] + c[n] - 1, c[first] + c[n]}
    found |= {c["MB_OUTPUT_COMMANDS_REGS"], c["MB_OUTPUT_COIL_FIRST"] + 16 * c["MB_OUTPUT_REGS"] - 1}
    return found - {0, 1}


def test_the_evidence_is_written_once():
    """Both sides read the evidence from the contract: the C front end's
    test and the Lua decoder's image map and whole-image tests name no
    address or count of it (a tvb offset, `off + 10`, is no address)."""
    assert EVIDENCE <= set(CONTRACT)
    numbers = evidence_numbers()
    c = code_of_c((ROOT / "plugins" / "vrshark" / "vrshark-frontends.c").read_text())
    c = c[c.index("mb_covers(guint"):c.index("find_mbtcp_port(const")]
    lua = code_of_lua((ROOT / "lua" / "eclink_modbus.lua").read_text())
    lua = lua[lua.index("local REGIONS = {"):lua.index("local TABLE_NAMES")] \
        + lua[lua.index("local function full_input("):lua.index("local READS")]
    for where, text in (("C", re.sub(r"\boff\s*\+\s*\d+", "off", c)), ("Lua", lua)):
        spelt = sorted(int(n) for n in re.findall(r"\b\d+\b", text) if int(n) in numbers)
        assert spelt == [], where
