"""The `vrshark` configuration profile (profile/vrshark/): its columns with
`tshark -C vrshark`, its colouring rules with `tshark --color`, and its
filter buttons compile."""
import os
import re
import shutil
import subprocess

import pytest

from conftest import PROFILE_DIR as PROFILE
from conftest import CAPTURES, ROOT, _world_dir, expert_infos, profile_buttons, profile_column_widths, profile_rules


@pytest.fixture(scope="module")
def profile_conf():
    """A configuration folder holding only the vrshark profile."""
    conf = _world_dir("vrshark-profile-")
    shutil.copytree(PROFILE, conf / "profiles" / "vrshark")
    for path in conf.rglob("*"):
        path.chmod(0o755 if path.is_dir() else 0o644)
    yield conf
    shutil.rmtree(conf, ignore_errors=True)


def run(conf, args, color=False):
    env = dict(os.environ, TZ="UTC", LC_ALL="C.UTF-8", WIRESHARK_CONFIG_DIR=str(conf))
    cmd = [str(ROOT / "tools" / "tshark")] + args
    if color:
        # tshark colours only on a terminal that says it has 24-bit colour
        env["COLORTERM"] = "truecolor"
        cmd = ["script", "-qc", " ".join(cmd), "/dev/null"]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "Lua Error" not in proc.stdout + proc.stderr
    return proc


def rule_colours():
    """{rule name: (background, foreground)} as 8-bit RGB tuples."""
    rules = {}
    for line in (PROFILE / "colorfilters").read_text().splitlines():
        m = re.match(r"@([^@]+)@[^@]+@\[(\d+),(\d+),(\d+)\]\[(\d+),(\d+),(\d+)\]$", line)
        if m:
            c = [int(x) >> 8 for x in m.groups()[1:]]
            rules[m.group(1)] = (tuple(c[:3]), tuple(c[3:]))
    return rules


def coloured_rows(conf, capture):
    """{frame number: (background, foreground)} from tshark --color."""
    out = run(conf, ["-C", "vrshark", "--color", "-n", "-r", str(ROOT / "captures" / capture)],
              color=True).stdout
    rows = {}
    for line in out.splitlines():
        m = re.match(r"(?:\x1b\[0m)?\x1b\[38;2;(\d+);(\d+);(\d+)m\x1b\[48;2;(\d+);(\d+);(\d+)m\s*(\d+) ", line)
        if m:
            c = [int(x) for x in m.groups()]
            rows[c[6]] = (tuple(c[3:6]), tuple(c[0:3]))
    return rows


def test_columns(profile_conf):
    out = run(profile_conf, ["-C", "vrshark", "-n", "-r", str(ROOT / "captures" / "eglink_states.pcap"),
                             "-c", "2"]).stdout.splitlines()
    # No., Time, Source, Protocol, Device, BU state, RU state, Armed RU, Watchdog, Info
    assert out[1].split()[:9] == ["2", "0.125000", "192.168.32.10", "EG-Link", "0x1001", "Stopped",
                                  "Stopped", "0xbeef", "VRPI"]


def test_colours_relays_open_and_healthy(profile_conf):
    rules = rule_colours()
    rows = coloured_rows(profile_conf, "eglink_states.pcap")
    for n in (1, 2, 3, 4, 5):  # BU Initial/Stopped/External link error/Blocked/Failed
        assert rows[n] == rules["vrshark: ES-Link relays open"], n
    rows = coloured_rows(profile_conf, "eglink_armed.pcap")
    assert set(rows.values()) == {rules["vrshark: EG-Link"]}


def test_colours_e010_and_bad_crc(profile_conf):
    rules = rule_colours()
    rows = coloured_rows(profile_conf, "mcmb2_polled_connect.pcap")
    assert rows[13] == rules["vrshark: E010 / fieldbus failure"]
    assert rows[11] == rules["vrshark: undefined status"]  # status 0x1 is not defined for polled bases
    assert rows[5] == rules["vrshark: MC-MB2-PN"]
    rows = coloured_rows(profile_conf, "eglink_crc_variants.pcap")
    assert rules["vrshark: bad CRC"] in set(rows.values())


def test_colours_eglink_undefined_statuses(profile_conf):
    rules = rule_colours()
    rows = coloured_rows(profile_conf, "eglink_range.pcap")
    # RU disabled 4, BU state 0x20, link statuses 7/200/9, RU state 5
    for n in (4, 9, 10, 11):
        assert rows[n] == rules["vrshark: undefined status"], n
    assert rows[8] == rules["vrshark: ES-Link relays open"]   # BU state 0x05: relays first


def test_filter_buttons_compile(profile_conf):
    buttons = profile_buttons()
    assert [b[0] for b in buttons] == ["Safety", "Faults", "Commands", "EG-Link", "EC-Link", "MC-MB2"]
    for label, expr in buttons:
        proc = run(profile_conf, ["-n", "-r", str(ROOT / "captures" / "eglink_armed.pcap"), "-c", "1",
                                  "-Y", expr])
        assert "isn't a valid" not in proc.stderr, (label, proc.stderr)
        assert "deprecated" not in proc.stderr, (label, proc.stderr)
    # a value string in quotes: Wireshark 4.6 warns on a bare one (the filter bar turns yellow)
    assert dict(buttons)["Faults"] == ('_ws.expert.severity >= "warning" && '
                                       "(eglink || eclink || mcmb2 || eclink_modbus || eclink_pnio)")


def test_colours_lost_and_repeated_packets(profile_conf):
    """[lost N] and [Repeated] are warnings: their own colour, not the healthy one."""
    rules = rule_colours()
    rows = coloured_rows(profile_conf, "eglink_analysis_lost.pcap")
    assert rows[13] == rows[15] == rules["vrshark: packets lost or repeated"]
    assert rows[12] == rules["vrshark: EG-Link"]
    rows = coloured_rows(profile_conf, "eglink_analysis_repeated.pcap")
    assert rows[9] == rows[15] == rules["vrshark: packets lost or repeated"]


def test_colours_eglink_gaps_have_their_own_rule(profile_conf):
    """A VRPI/VRPO gap is coloured by a rule of that name (not "watchdog stalled")."""
    rules = rule_colours()
    rows = coloured_rows(profile_conf, "eglink_analysis_vrpi_gap.pcap")
    assert rows[16] == rows[20] == rules["vrshark: VRPI / VRPO gap"]
    assert "eglink" not in [ln for ln in (PROFILE / "colorfilters").read_text().splitlines()
                            if ln.startswith("@vrshark: watchdog stalled@")][0]


def test_colours_a_failed_command_where_the_pass_puts_it(profile_conf):
    """docs/findings.md "How findings read": the first packet past the deadline
    of VRCI 8 (frame 61) has the colour of a command not acknowledged, not
    the command (frame 5), on every pass: a live packet list colours a row
    when it first draws it, before the deadline (test_gui_live). The
    Commands button shows it."""
    rules = rule_colours()
    rows = coloured_rows(profile_conf, "eglink_analysis_vrci_unacked.pcap")
    assert rows[61] == rules["vrshark: command not acknowledged"]
    assert rows[5] != rules["vrshark: command not acknowledged"]
    assert [n for n, c in rows.items() if c == rules["vrshark: command not acknowledged"]] == [61]
    assert 61 in _matching(profile_conf, "eglink_analysis_vrci_unacked.pcap", _button("Commands"))
    for two_pass in (False, True):
        for capture, frames in (("eglink_analysis_vrci_unacked.pcap", [61]),
                                ("eglink_analysis_vrco_unacked.pcap", [61, 123, 128]),
                                ("eclink_modbus_faults.pcap", [28, 34]), ("eclink_pnio_connect.pcap", [76])):
            assert _matching(profile_conf, capture, rule_filter("vrshark: command not acknowledged"),
                             two_pass) == frames, (capture, two_pass)


def rule_filter(name):
    return dict((n, f) for n, f in profile_rules())[name]


def _button(label):
    return dict(profile_buttons())[label]


def _matching(conf, capture, expr, two_pass=False):
    out = run(conf, ["-n"] + (["-2"] if two_pass else []) + ["-r", str(ROOT / "captures" / capture), "-Y", expr,
                     "-T", "fields", "-e", "frame.number"]).stdout
    return [int(x) for x in out.split()]


# filter button -> the protocols whose findings it must show
BUTTON_PROTOCOLS = {"EG-Link": ["eglink"], "EC-Link": ["eclink", "eclink_modbus", "eclink_pnio"],
                    "MC-MB2": ["mcmb2"]}
FINDING_CAPTURES = ["eglink_analysis_vrci_unacked.pcap", "eglink_analysis_vrpi_gap.pcap",
                    "eclink_modbus_faults.pcap", "eclink_modbus_commands.pcap", "eclink_pnio_connect.pcap",
                    "clockstep_modbus.pcap", "mcmb2_duplex_watchdog.pcap", "mcmb2_polled_connect.pcap"]


@pytest.mark.parametrize("two_pass", [False, True], ids=["one_pass", "two_pass"])
def test_protocol_buttons_show_every_finding_of_their_protocol(profile_conf, tshark, two_pass):
    """The EG-Link, EC-Link and MC-MB2 buttons show every frame with a finding
    (an expert info named under the protocol), also those that sit on frames
    of the transport only: a poll gap, or the one-pass [unacked], on the
    PLC's request (eclink_modbus, no eclink image in it)."""
    checked = set()
    for capture in FINDING_CAPTURES:
        found = {}
        for frame, name, *_ in expert_infos(tshark.json(ROOT / "captures" / capture, two_pass=two_pass)):
            found.setdefault(name.split(".")[0], set()).add(frame)
        for label, protos in BUTTON_PROTOCOLS.items():
            want = set().union(*(found.get(p, set()) for p in protos))
            if not want:
                continue
            shown = set(_matching(profile_conf, capture, _button(label), two_pass))
            assert sorted(want - shown) == [], (label, capture)
            checked.add(label)
    assert checked == set(BUTTON_PROTOCOLS)


def test_safety_button_shows_the_gap_rows(profile_conf):
    assert {16, 20} <= set(_matching(profile_conf, "eglink_analysis_vrpi_gap.pcap", _button("Safety")))


def test_commands_button_shows_the_acknowledgements_of_every_protocol(profile_conf):
    """EC-Link over PROFINET acknowledgements too (as over Modbus/TCP)."""
    acks = _matching(profile_conf, "eclink_pnio_connect.pcap",
                     "eclink_pnio.cmd_from_ru.ack || eclink_pnio.cmd_to_ru.ack")
    assert acks
    assert set(acks) <= set(_matching(profile_conf, "eclink_pnio_connect.pcap", _button("Commands")))


def test_healthy_eglink_is_not_wiresharks_tcp_or_udp_colour(profile_conf):
    """Plain TCP/UDP rows (Wireshark's own rules after ours) must not pass for healthy EG-Link."""
    ours = rule_colours()["vrshark: EG-Link"][0]
    theirs = {}
    for line in open("/usr/share/wireshark/colorfilters").read().splitlines():
        m = re.match(r"@(TCP|UDP)@[^@]+@\[(\d+),(\d+),(\d+)\]", line)
        if m:
            theirs[m.group(1)] = tuple(int(x) >> 8 for x in m.groups()[1:])
    assert set(theirs) == {"TCP", "UDP"}
    for name, rgb in theirs.items():
        assert sum((a - b) ** 2 for a, b in zip(ours, rgb)) ** 0.5 >= 40, name


COLUMNS = ["No.", "Time", "Source", "Protocol", "Device", "BU state", "RU state", "Armed RU",
           "Age ms", "Info"]


def packet_list(conf, capture):
    """{frame number: {column title: text}} of the packet list as tshark prints
    the profile's columns (-T tabs; column fields by title, _ws.col.Device,
    exist in Wireshark 4.0 only)."""
    out = run(conf, ["-C", "vrshark", "-T", "tabs", "-n", "-2", "-r", str(ROOT / "captures" / capture)]).stdout
    rows = {}
    for line in out.splitlines():
        cells = [c.strip() for c in line.split("\t")]
        if cells[0].isdigit():
            rows[int(cells[0])] = dict(zip(COLUMNS, cells))
    return rows


def _device_column(conf, capture, frames):
    rows = packet_list(conf, capture)
    return [rows[n]["Device"] for n in frames]


def test_profile_column_titles():
    text = (PROFILE / "preferences").read_text()
    assert re.findall(r'^\t"([^"]+)", "%', text, re.M) == COLUMNS


def test_watchdog_column_reads_whole_milliseconds(profile_conf):
    """The MC-MB2 watchdog age and the EC-Link PCI/PCO ages in whole ms (a
    time field there prints nine decimals and is cut off)."""
    rows = packet_list(profile_conf, "mcmb2_duplex_watchdog.pcap")
    assert [rows[n]["Age ms"] for n in (23, 25, 27, 28)] == ["1200", "1400", "0", "1600"]
    rows = packet_list(profile_conf, "eclink_modbus_faults.pcap")
    assert rows[21]["Age ms"] == "700"           # PCI, input image
    assert rows[30]["Age ms"] == "2050"          # PCO, output image
    rows = packet_list(profile_conf, "eclink_pnio_connect.pcap")
    assert rows[31]["Age ms"] == "625"
    assert rows[72]["Age ms"] == "2125"
    assert not [r for r in rows.values() if "." in r["Age ms"]]


def test_device_column_names_the_device_on_every_protocol(profile_conf):
    """EC-Link over Modbus/TCP: the BU's server address, requests and
    responses alike; PROFINET: the FrameID in hex, as the tree shows it."""
    assert _device_column(profile_conf, "eclink_modbus_basic.pcap", [5, 6, 13]) == ["192.168.2.41:502"] * 3
    assert _device_column(profile_conf, "eclink_pnio_connect.pcap", [3, 4]) == ["0x8010", "0x8011"]
    assert _device_column(profile_conf, "mcmb2_duplex_watchdog.pcap", [3, 4]) == ["0x8003", "0x8004"]
    assert _device_column(profile_conf, "eglink_states.pcap", [2]) == ["0x1001"]


def test_device_column_on_a_second_controller_of_a_shared_group(profile_conf, tshark):
    """Two BUs and two controllers on one group: a controller's VRPOs name its
    BU, also those before the acknowledgement that joined it (frame 18 for
    10.0.0.12; second pass and GUI). One pass says the BU is not known yet."""
    cap = "eglink_analysis_shared_group.pcap"
    assert _device_column(profile_conf, cap, [3, 4, 17, 18, 22]) == ["0x1001", "0x2002", "0x2002", "0x2002",
                                                                      "0x2002"]
    one = tshark.frames(ROOT / "captures" / cap, ["eglink.analysis.device", "eglink.analysis.bu_origin"])
    assert one[4] == {"eglink.analysis.device": "BU not known", "eglink.analysis.bu_origin": ""}
    assert one[22] == {"eglink.analysis.device": "0x2002", "eglink.analysis.bu_origin": "0x2002"}
    assert not [n for n, r in one.items() if not r["eglink.analysis.device"]]


# The packet list's monospace font at 1680 px (measured on the screenshots of
# tests/test_gui_installed.py): 7.8 px a character (the Info text of
# eclink_modbus_faults.pcap frame 28, 82 characters, spans 636 px); a cell's
# text sits 4-5 px from its left edge and 4 px from its right one. The No.
# column takes another 24 px for the related-frame marks, and the vertical
# scroll bar with the packet list's minimap beside it 50 px (the Info column
# ends at x 1630 on those screenshots). (test_long_capture_columns_not_cut
# checks No., Time and Source in the GUI.)
ADVANCE, MARGIN, MARKS, SCROLL_BAR = 7.8, 8, 24, 50


def needs(text, title=None):
    """Pixels a cell needs for the text."""
    return ADVANCE * len(text) + MARGIN + (MARKS if title == "No." else 0)


def test_every_column_has_a_width(tshark):
    """profile/vrshark/recent gives each column of the profile a width, keyed
    as Wireshark keys it (a custom column by its fields), wide enough at
    1680 px for the longest texts the columns hold: a MAC name as Wireshark
    4.6 resolves it, and in Info, beside them, Modbus's own text of every
    input image read of eclink_modbus_faults.pcap with its first tag."""
    prefs = re.findall(r'^\t"([^"]+)", "([^"]+)"', (PROFILE / "preferences").read_text(), re.M)
    pairs = profile_column_widths()
    keys = ['"%s"' % fmt.rsplit(":", 2)[0] if fmt.startswith("%Cus:") else fmt for _, fmt in prefs]
    assert [k for k, _ in pairs] == keys
    width = dict(zip([t for t, _ in prefs], [w for _, w in pairs]))
    for title, text in [("No.", "1000000"), ("Time", "12345.678901"), ("Source", "Siemens_00:00:01"),
                        ("Source", "HMSIndustria_00:00:02"), ("Source", "255.255.255.255"),
                        ("Protocol", "Modbus/TCP"), ("Device", "192.168.2.41:502"),
                        ("BU state", "External link error"), ("RU state", "Disarmed"), ("Armed RU", "0x1234")]:
        assert width[title] >= needs(text, title), (title, text)
    # every title whole
    for title, w in width.items():
        assert w >= needs(title, title), title
    info = 1680 - SCROLL_BAR - (sum(width.values()) - width["Info"])
    rows = tshark.frames(CAPTURES / "eclink_modbus_faults.pcap", ["modbus.func_code", "_ws.col.Info"], two_pass=True)
    infos = [v["_ws.col.Info"] for v in rows.values() if v["modbus.func_code"] == "4"]
    # (the first bracket after Modbus's text: a tag, or the image summary)
    texts = [t[:t.index("]") + 1] for t in infos if " [" in t and " [EC-Link" not in t[:t.index("]")]]
    assert "Response: Trans:     9; Unit:   1, Func:   4: Read Input Registers [PCI stalled 0.700 s]" in texts
    assert "   Query: Trans:     9; Unit:   1, Func:   4: Read Input Registers [poll gap 0.700 s]" in texts
    assert [t for t in texts if needs(t) > info] == []
