"""vrshark-report's model: which device a packet belongs to, candidates the
dissectors hint at, failed commands, the detail a finding names, the final
state in the HTML device table.

The model is fed rows directly where the plugins that give those rows are
newer than this checkout (candidates, the failed command's warning in one
pass); the rest goes through the checkout's tools/vrshark-report and the
command `cmake --install` puts into a fresh home, on captures of real
sockets (Python's socket module on lo, captured with dumpcap) as well as the
generated ones.
"""
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import xml.etree.ElementTree as ET

import pytest

from conftest import CAPTURES, ROOT

sys.path.insert(0, str(ROOT / "tools"))
from capgen import eglink as eg  # noqa: E402
from report import catalog, model, rows  # noqa: E402

REPORT = ROOT / "tools" / "vrshark-report"


# --- the model, fed rows ----------------------------------------------------------------

def row(frame, t=None, **fields):
    """One row of rows.Rows: fields by name (dots as __), the rest empty."""
    cols = [""] * len(rows.ALL_FIELDS)
    cols[0], cols[1] = str(frame), "%.6f" % (frame * 0.1 if t is None else t)
    for name, value in fields.items():
        cols[rows.COL[name.replace("__", ".")]] = str(value)
    return cols


def run_model(rowlist, prefs=()):
    cap = model.Capture("x.pcap", model.limits_from_prefs(prefs))
    for r in rowlist:
        cap.add(r)
    return cap.finish()


def entries(rep):
    return [(e["frame"], e["severity"], e["device"], e["text"]) for e in rep["timeline"]]


MB = dict(ip__src="192.168.2.10", ip__dst="192.168.2.41", tcp__srcport=40000, tcp__dstport=502)
MB_SETTING = "eclink_modbus.servers:192.168.2.41"


def modbus_candidate(frame):
    return row(frame, eclink_modbus__candidate=1, eclink_modbus__candidate_setting=MB_SETTING, **MB)


def modbus_image(frame):
    return row(frame, eclink_modbus__table="input", eclink__image="input", eclink__bu_state="0x11",
               eclink__pci=frame % 256, **MB)


def test_modbus_candidate_never_recognised():
    rep = run_model([modbus_candidate(f) for f in range(1, 6)])
    assert [(d["id"], d["kind"], d["name"], d["layout"], d["frames"], d["first_frame"], d["last_frame"])
            for d in rep["devices"]] == [
        (1, "candidate", "Modbus/TCP server 192.168.2.41:502, not decoded",
         "not recognised; to decode it: -o eclink_modbus.servers:192.168.2.41", 5, 1, 5)]
    assert rep["devices"][0]["address"] == {"server": "192.168.2.41", "port": 502, "setting": MB_SETTING}
    assert entries(rep) == [
        (1, "warning", 1, "Modbus/TCP server 192.168.2.41:502 looks like an EC-Link BU but was not "
         "recognised; to decode it: -o eclink_modbus.servers:192.168.2.41")]
    assert rep["timeline"][0]["field"] == "eclink_modbus.candidate"
    assert rep["timeline"][0]["last_frame"] == 5
    assert catalog.severity_at_least(rep["timeline"][0]["severity"], "warning")  # --fail-on warn


def test_modbus_candidate_recognised_later_is_not_listed():
    """In one pass a BU's first frames carry the note until it is recognised."""
    rep = run_model([modbus_candidate(f) for f in range(1, 4)] + [modbus_image(f) for f in range(4, 9)])
    assert [(d["kind"], d["name"]) for d in rep["devices"]] == [
        ("eclink_modbus", "EC-Link BU, Modbus/TCP server 192.168.2.41:502")]
    assert [e for e in rep["timeline"] if e["field"] == "eclink_modbus.candidate"] == []


def test_modbus_candidate_after_the_bu_was_dropped_is_listed():
    rep = run_model([modbus_image(f) for f in range(1, 5)] + [modbus_candidate(f) for f in range(5, 8)])
    assert [(d["id"], d["kind"]) for d in rep["devices"]] == [(1, "eclink_modbus"), (2, "candidate")]
    assert [(e["frame"], e["device"], e["field"]) for e in rep["timeline"]
            if e["field"] == "eclink_modbus.candidate"] == [(5, 2, "eclink_modbus.candidate")]


@pytest.mark.parametrize("prefs, layout", [
    ((), "detection always"),
    (("eclink_modbus.servers:192.168.2.7,192.168.2.41",), "listed in eclink_modbus.servers"),
    (("eclink_modbus.servers:192.168.2.41:502",), "listed in eclink_modbus.servers"),
])
def test_modbus_layout_says_how_it_was_found(prefs, layout):
    rep = run_model([modbus_image(1)], prefs)
    assert [d["layout"] for d in rep["devices"]] == [layout]


def test_modbus_candidate_on_another_port():
    setting = "eclink_modbus.servers:192.168.2.41:5020"
    rep = run_model([row(1, eclink_modbus__candidate=1, eclink_modbus__candidate_setting=setting,
                         ip__src="192.168.2.41", ip__dst="192.168.2.10", tcp__srcport=5020,
                         tcp__dstport=40000)])
    assert entries(rep) == [
        (1, "warning", 1, "Modbus/TCP server 192.168.2.41:5020 looks like an EC-Link BU but was not "
         "recognised; to decode it: -o eclink_modbus.servers:192.168.2.41:5020")]


PN = dict(eth__src="00:30:11:00:00:02", eth__dst="00:1b:1b:00:00:01")
PN_SETTING = "mcmb2.layouts:0x8001/0x8002=duplex:26/2,a8@4"


def pnio_candidate(frame, frame_id=0x8001, **kw):
    macs = PN if frame_id == 0x8001 else dict(eth__src=PN["eth__dst"], eth__dst=PN["eth__src"])
    return row(frame, mcmb2__candidate=1, mcmb2__candidate_setting=PN_SETTING, pn_rt__frame_id=frame_id,
               **dict(macs, **kw))


def test_pnio_candidate_never_settled():
    rep = run_model([pnio_candidate(f, 0x8001 if f % 2 else 0x8002) for f in range(1, 7)])
    assert [(d["kind"], d["name"], d["frames"]) for d in rep["devices"]] == [
        ("candidate", "PROFINET IO 00:30:11:00:00:02 to 00:1b:1b:00:00:01 (FrameID 0x8001, 0x8002), "
         "not decoded", 6)]
    assert entries(rep) == [
        (1, "warning", 1, "cyclic frames of PROFINET IO 00:30:11:00:00:02 to 00:1b:1b:00:00:01 "
         "(FrameID 0x8001, 0x8002) look like an MC-MB2-PN or EC-Link device but were not recognised; "
         "to decode it: -o mcmb2.layouts:0x8001/0x8002=duplex:26/2,a8@4")]


def test_pnio_candidate_settled_later_is_not_listed():
    decoded = [row(f, mcmb2__direction="uplink", mcmb2__system="duplex", mcmb2__layout="inferred",
                   pn_rt__frame_id=0x8001, **PN) for f in range(4, 8)]
    rep = run_model([pnio_candidate(f) for f in range(1, 4)] + decoded)
    assert [d["kind"] for d in rep["devices"]] == ["mcmb2"]
    assert rep["timeline"] == []


def eglink_command_rows(*experts):
    """A VRCI (frame 5) and the frame past its deadline (61) with the given experts."""
    base = dict(eglink__type="VRPI", eglink__analysis__bu_stream=0, udp__dstport=5825,
                ip__src="192.168.32.10", ip__dst="239.255.42.20")
    out = [row(5, eglink__command_id=5, **dict(base, eglink__type="VRCI"))]
    extra = {}
    for name, frame in experts:
        if frame == 61:
            extra[name] = 1
            extra["eglink.analysis.failed_command"] = 5
    out.append(row(61, **dict(base, **{k.replace(".", "__"): v for k, v in extra.items()})))
    for name, frame in experts:
        if frame == 5:
            out[0][rows.COL[name]] = "1"
    return out


@pytest.mark.parametrize("experts, want", [
    # one pass of a plugin that names the failure in one pass
    ([("eglink.analysis.vrci_unacked", 61)],
     (61, "warning", 1, "VRCI of frame 5 not acknowledged in time: the command failed")),
    # one pass of an older plugin: the note only
    ([("eglink.analysis.vrci_deadline", 61)], (61, "note", 1, "deadline of the VRCI of frame 5 passed")),
    # both on one frame, and the second pass's placement: one entry, the warning
    ([("eglink.analysis.vrci_unacked", 61), ("eglink.analysis.vrci_deadline", 61)],
     (61, "warning", 1, "VRCI of frame 5 not acknowledged in time: the command failed")),
    ([("eglink.analysis.vrci_unacked", 5), ("eglink.analysis.vrci_deadline", 61)],
     (5, "warning", 1, "VRCI of frame 5 not acknowledged in time: the command failed")),
])
def test_failed_command_is_one_entry(experts, want):
    assert entries(run_model(eglink_command_rows(*experts))) == [want]


def test_failed_commands_are_not_a_burst():
    """Two commands failing within 2 s are two entries, each naming its command."""
    base = dict(eclink_modbus__table="input", eclink__image="input", **MB)
    rep = run_model([row(28, t=2.8, eclink_modbus__cmd_from_ru__late=1, eclink_modbus__cmd_from_ru_in=17,
                         **base),
                     row(29, t=2.9, eclink_modbus__cmd_from_ru__late=1, eclink_modbus__cmd_from_ru_in=18,
                         **base)])
    assert entries(rep) == [
        (28, "warning", 1, "command from RU of frame 17 not echoed by CAO in time: the command failed, the BU shows \"EC: Bad data\""),
        (29, "warning", 1, "command from RU of frame 18 not echoed by CAO in time: the command failed, the BU shows \"EC: Bad data\"")]


def test_every_finding_with_a_value_names_it():
    """Every catalog finding about a value has a detail function (details.py), and
    each gives the value and where from a row that carries it."""
    from report.details import DETAILS
    # not about one value: RU fields or terminal data that are not 0 (the tree shows which)
    several = {"eglink.armed_ru.unarmed_data", "eclink.unarmed_not_zero", "mcmb2.data_not_zero"}
    valued = [n for n, (_, role, what) in catalog.EXPERTS.items()
              if role == "finding" and n not in several
              and any(w in what for w in ("undefined", "range", "over 100", "not 0", "not GOOD", "unknown"))]
    assert [n for n in valued if n not in DETAILS] == []
    slot = row(9, mcmb2__slot="1,2,3,4", mcmb2__slot__status="0x01,0x01,0x42,0x0f")
    assert DETAILS["mcmb2.slot.status.undefined"](slot) == " 0x42 in slot 3"
    joy = row(1, eclink__joystick1=10, eclink__joystick2=-1200)
    assert DETAILS["eclink.joystick.range"](joy) == ": joystick 2 at -1200"
    assert DETAILS["eglink.link_status.unknown"](row(1, eglink__c_link_status=9)) == ": C-Link status 0x09"
    assert DETAILS["mcmb2.layout_mismatch"](row(1, mcmb2__uplink_size=20, mcmb2__downlink_size=10)) == \
        ": the frame has Y=20, Z=10"
    assert DETAILS["eglink.bu_state.unknown"](row(1)) == ""  # value not in the row: no detail


def eglink_row(frame, typ, stream="", port=None, src="192.168.32.10", **kw):
    port = port or (5825 if typ.endswith("I") else 5827)
    return row(frame, eglink__type=typ, eglink__analysis__bu_stream=stream, udp__dstport=port,
               ip__src=src, ip__dst="239.255.42.20", **kw)


def test_controller_packets_before_the_bus_first_vrpi():
    """One pass joins a controller to its BU at the BU's first VRPI: the VRPO before it is the BU's."""
    rep = run_model([eglink_row(1, "VRPO", src="192.168.32.20"), eglink_row(2, "VRPO", src="192.168.32.20"),
                     eglink_row(3, "VRPI", 0, eglink__origin="0x1001"),
                     eglink_row(4, "VRPO", 0, src="192.168.32.20")])
    assert [(d["name"], d["frames"], d["first_frame"], d["layout"]) for d in rep["devices"]] == [
        ("EG-Link BU 0x1001 (192.168.32.10 to 239.255.42.20:5825)", 4, 1,
         "TS-0006 on UDP ports 5825, 5827: by port")]


def test_second_bu_on_a_shared_channel_is_its_own():
    """A controller the analysis does not join to either BU of its channel is
    listed apart (issue 45: not guessed to be the first BU's)."""
    rep = run_model([eglink_row(1, "VRPI", 0, eglink__origin="0x1001"),
                     eglink_row(2, "VRPI", 1, src="192.168.32.11", eglink__origin="0x1002"),
                     eglink_row(3, "VRPO", src="192.168.32.20")])
    assert [(d["id"], d["name"], d["frames"]) for d in rep["devices"]] == [
        (1, "EG-Link BU 0x1001 (192.168.32.10 to 239.255.42.20:5825)", 1),
        (2, "EG-Link BU 0x1002 (192.168.32.11 to 239.255.42.20:5825)", 1),
        (3, "EG-Link controller 192.168.32.20 to 239.255.42.20:5827, BU not known (no command "
            "acknowledged between it and a BU of the group: pairing unknown)", 1)]


def test_controller_joined_later_is_its_bus():
    """Joined by an acknowledgement (its packets carry the BU's stream from
    then on): its packets from before are the BU's too, and no device is
    left apart."""
    rep = run_model([eglink_row(1, "VRPI", 0, eglink__origin="0x1001"),
                     eglink_row(2, "VRPI", 1, src="192.168.32.11", eglink__origin="0x1002"),
                     eglink_row(3, "VRPO", src="192.168.32.20"),
                     eglink_row(4, "VRAO", 1, src="192.168.32.20"),
                     eglink_row(5, "VRPI", 0, eglink__origin="0x1001")])
    assert [(d["id"], d["name"], d["frames"], d["first_frame"]) for d in rep["devices"]] == [
        (1, "EG-Link BU 0x1001 (192.168.32.10 to 239.255.42.20:5825)", 2, 1),
        (2, "EG-Link BU 0x1002 (192.168.32.11 to 239.255.42.20:5825)", 3, 2)]


@pytest.mark.parametrize("prefs, layout", [
    ((), "TS-0006 on UDP port 6001: heuristic"),
    (("eglink.input_port:5825,5999",), "TS-0006 on UDP port 6001: by port"),
])
def test_layout_names_the_ports_seen(prefs, layout):
    rep = run_model([eglink_row(1, "VRAO", port=6001, src="192.168.32.20")], prefs)
    assert [(d["name"], d["layout"]) for d in rep["devices"]] == [
        ("EG-Link BU of unknown origin (controller 192.168.32.20 to 239.255.42.20:6001)", layout)]


# --- through the command: the checkout's and the installed one -----------------------------

@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """bin/vrshark-report as `cmake --install --component report` puts it into a fresh home."""
    home = tmp_path_factory.mktemp("report-home")
    build = home / "build"
    for cmd in (["cmake", "-S", ROOT, "-B", build], ["cmake", "--install", build, "--component", "report"]):
        proc = subprocess.run([str(c) for c in cmd], capture_output=True, text=True,
                              env=dict(os.environ, HOME=str(home)))
        assert proc.returncode == 0, proc.stdout + proc.stderr
    return home / ".local" / "bin" / "vrshark-report"


@pytest.fixture(params=["checkout", "installed"])
def vrshark_report(request, conf_dir):
    """vrshark_report(*args) -> CompletedProcess; the installed command runs the
    checkout's tools/tshark ($TSHARK) so that both read with these plugins."""
    env = dict(os.environ, TZ="UTC", LC_ALL="C.UTF-8", WIRESHARK_CONFIG_DIR=str(conf_dir))
    if request.param == "installed":
        cmd = request.getfixturevalue("installed")
        env["TSHARK"] = str(ROOT / "tools" / "tshark")
    else:
        cmd = REPORT

    def run(*args):
        return subprocess.run([str(cmd)] + [str(a) for a in args], capture_output=True, text=True,
                              env=env, cwd=str(ROOT), stdin=subprocess.DEVNULL, timeout=600)
    return run


def mcast_socket():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 1)
    s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton("127.0.0.1"))
    s.bind(("127.0.0.1", 0))
    return s


def capture_on_lo(path, sockets, send):
    """Run send() while dumpcap captures on lo what the sockets send (only
    theirs: other tests may send EG-Link on lo at the same time)."""
    dumpcap = shutil.which("dumpcap")
    if not dumpcap:
        pytest.skip("dumpcap is not installed: cannot capture on lo")
    ports = " or ".join("src port %d" % s.getsockname()[1] for s in sockets)
    proc = subprocess.Popen([dumpcap, "-q", "-i", "lo", "-f", "udp and dst host 239.255.42.20 and (%s)" % ports,
                             "-w", str(path)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 10
        while not (path.exists() and path.stat().st_size > 0):
            if proc.poll() is not None or time.monotonic() > deadline:
                pytest.skip("cannot capture on lo: %s" % (proc.stderr.read() if proc.poll() is not None
                                                          else "dumpcap did not start"))
            time.sleep(0.05)
        time.sleep(0.2)
        send()
        time.sleep(0.3)
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=10)
    path.chmod(0o644)


@pytest.fixture(scope="module")
def socket_captures(tmp_path_factory):
    """Real-socket EG-Link on lo: the controller's VRPO before the BU's first VRPI
    (with the checkout's BU and controller packets); a lone VRAO on port 6001."""
    folder = tmp_path_factory.mktemp("report-sockets")
    folder.chmod(0o755)
    session, vrao = folder / "controller_first.pcap", folder / "vrao_6001.pcap"

    bu, ctrl, ctrl_6001 = mcast_socket(), mcast_socket(), mcast_socket()

    def send_session():
        for i in range(6):
            ctrl.sendto(eg.packet("VRPO", eg.vrpo(0, eg.machine_data(i)), serial=i), ("239.255.42.20", 5827))
            time.sleep(0.01)
            bu.sendto(eg.packet("VRPI", eg.armed(), origin=0x1001, serial=i), ("239.255.42.20", 5825))
            time.sleep(0.01)

    def send_vrao():
        ctrl_6001.sendto(eg.packet("VRAO", eg.ack(5)), ("239.255.42.20", 6001))

    capture_on_lo(session, (bu, ctrl), send_session)
    capture_on_lo(vrao, (ctrl_6001,), send_vrao)
    return session, vrao


def devices(proc):
    assert proc.returncode in (0, 1), proc.stderr
    return json.loads(proc.stdout)["captures"][0]["devices"]


def test_socket_controller_first_is_one_device(vrshark_report, socket_captures, tmp_path):
    session = socket_captures[0]
    devs = devices(vrshark_report("--json", session))
    assert [(d["kind"], d["name"], d["frames"], d["first_frame"], d["last_frame"], d["layout"])
            for d in devs] == [
        ("eglink", "EG-Link BU 0x1001 (127.0.0.1 to 239.255.42.20:5825)", 12, 1, 12,
         "TS-0006 on UDP ports 5825, 5827: by port")]
    junit = tmp_path / "r.xml"
    proc = vrshark_report("--junit", junit, session)
    assert proc.returncode == 0, proc.stderr
    assert [c.get("name") for c in ET.parse(junit).getroot().iter("testcase")] == [
        "EG-Link BU 0x1001 (127.0.0.1 to 239.255.42.20:5825)"]


def test_socket_heuristic_port(vrshark_report, socket_captures):
    devs = devices(vrshark_report("--json", socket_captures[1]))
    assert [(d["name"], d["layout"], d["address"]["ports"]) for d in devs] == [
        ("EG-Link BU of unknown origin (controller 127.0.0.1 to 239.255.42.20:6001)",
         "TS-0006 on UDP port 6001: heuristic", [6001])]
    text = vrshark_report(socket_captures[1]).stdout
    assert "5999" not in text


def test_finding_detail_and_gate(vrshark_report):
    proc = vrshark_report("--fail-on", "error", "captures/mcmb2_polled_connect.pcap")
    assert proc.returncode == 1
    assert "     0.400       9  error     [1]  undefined slot status 0x03 in slot 3" in proc.stdout.splitlines()
    assert proc.stderr == ("vrshark-report: FAIL (--fail-on error): 4 finding(s) at error or above; first: "
                           "captures/mcmb2_polled_connect.pcap frame 9: undefined slot status 0x03 in slot 3\n")


@pytest.mark.parametrize("name, gate, status", [
    ("eglink_analysis_vrpi_gap.pcap", "error", 1),      # a gap is an error, as docs/findings.md says
    ("eclink_pnio_connect.pcap", "error", 1),           # so is a PCI/PCO stall
    ("eglink_analysis_repeated.pcap", "error", 0),      # a repeated packet is a warning
    ("eglink_analysis_repeated.pcap", "warn", 1),
])
def test_gate_follows_the_catalog(vrshark_report, name, gate, status):
    proc = vrshark_report("--fail-on", gate, "captures/" + name)
    assert proc.returncode == status, proc.stderr


def test_docs_text_example_is_the_output(vrshark_report):
    """docs/report.md's text example is what the report prints."""
    text = (ROOT / "docs" / "report.md").read_text()
    start = text.index("    == captures/eglink_analysis_vrpo_gap.pcap")
    example = text[start:text.index("\n\n", start) + 1]
    proc = vrshark_report("captures/eglink_analysis_vrpo_gap.pcap")
    assert "".join("    " + ln + "\n" for ln in proc.stdout.splitlines()) == example


def test_generated_capture_controller_first(vrshark_report, tmp_path):
    """crane_eglink.pcap starts with the controller's VRPO too: one BU, one test case."""
    junit = tmp_path / "r.xml"
    proc = vrshark_report("--json", "--junit", junit, "captures/crane_eglink.pcap")
    assert [(d["name"], d["frames"], d["first_frame"]) for d in devices(proc)] == [
        ("EG-Link BU 0x2c01 (192.168.32.10 to 239.255.42.20:5825)", 17, 1)]
    assert len(list(ET.parse(junit).getroot().iter("testcase"))) == 1


def test_docs_gate_example_is_the_output(vrshark_report, tshark):
    """docs/report.md's gate line is what the command says on the fault captures
    (its count with the EC-Link failed commands as warnings, as one pass gives
    them; a plugin that gives them only on the second pass lists their notes)."""
    line = next(ln.strip() for ln in (ROOT / "docs" / "report.md").read_text().splitlines()
                if ln.startswith("    vrshark-report: FAIL (--fail-on warn)"))
    captures = sorted(str(p.relative_to(ROOT)) for p in CAPTURES.glob("*faults*.pcap"))
    proc = vrshark_report(*captures, "--fail-on", "warn")
    assert proc.returncode == 1
    warnings = len(tshark.field(CAPTURES / "eclink_modbus_faults.pcap", "frame.number", display_filter=(
        "eclink_modbus.cmd_from_ru.late || eclink_modbus.cmd_to_ru.late") + " && frame.number == 28"))
    count = int(line.split("): ")[1].split(" ")[0])
    assert proc.stderr == line.replace(" %d finding" % count, " %d finding" % (count - 2 + 2 * warnings)) + "\n"


def test_html_device_table_has_the_last_state(vrshark_report, tmp_path):
    pytest.importorskip("plotly", reason="plotly is not installed (tools/setup installs it)")
    page = tmp_path / "r.html"
    proc = vrshark_report("--html", page, "captures/mcmb2_polled_connect.pcap", "captures/eglink_armed.pcap")
    assert proc.returncode == 0, proc.stderr
    html = page.read_text()
    assert "<th>first state</th><th>last state</th>" in html
    assert ("<td>status normal mode, slot 1 terminal 1 present, slot 2 terminal 2 present, "
            "slot 3 terminal 3 present, slot 4 not used</td>"
            "<td>status normal mode, slot 1 terminal 1 present, slot 2 terminal 5 active stop, "
            "slot 3 terminal 3 present, slot 4 not used</td>") in html
    assert "<td>BU state Armed, RU state Enabled (RU 0xbeef)</td><td>as first</td>" in html


# --- candidates through the command (plugins that give the candidate notes) ----------------

EXCERPT = "captures/eclink_modbus_excerpt.pcap"


@pytest.fixture(scope="module")
def with_candidates(tshark):
    fields = tshark.run(["-G", "fields"], allow_errors=True).stdout
    if "\teclink_modbus.candidate\t" not in fields or not (ROOT / EXCERPT).is_file():
        pytest.skip("the plugin gives no eclink_modbus.candidate note (or %s is missing)" % EXCERPT)


def test_candidate_listed_with_its_setting(vrshark_report, with_candidates):
    """A BU's excerpt too short for its evidence: a candidate, a warning naming the setting."""
    proc = vrshark_report("--json", "--fail-on", "warn", EXCERPT)
    assert proc.returncode == 1, proc.stderr
    cap = json.loads(proc.stdout)["captures"][0]
    assert [(d["kind"], d["name"], d["layout"]) for d in cap["devices"]] == [
        ("candidate", "Modbus/TCP server 192.168.2.41:502, not decoded",
         "not recognised; to decode it: -o eclink_modbus.servers:192.168.2.41")]
    assert [(e["severity"], e["field"], e["text"]) for e in cap["timeline"]] == [
        ("warning", "eclink_modbus.candidate", "Modbus/TCP server 192.168.2.41:502 looks like an EC-Link BU "
         "but was not recognised; to decode it: -o eclink_modbus.servers:192.168.2.41")]
    # the setting it names decodes it: a BU, no candidate
    proc = vrshark_report("--json", "--fail-on", "warn", "-o", "eclink_modbus.servers:192.168.2.41", EXCERPT)
    cap = json.loads(proc.stdout)["captures"][0]
    assert [(d["kind"], d["name"], d["layout"]) for d in cap["devices"]] == [
        ("eclink_modbus", "EC-Link BU, Modbus/TCP server 192.168.2.41:502", "listed in eclink_modbus.servers")]
    assert [e for e in cap["timeline"] if e["field"] == "eclink_modbus.candidate"] == []


def test_bu_recognised_later_is_no_candidate(vrshark_report, with_candidates):
    """In one pass every BU's first frames carry the note: none of the BUs is a
    candidate (the plant on port 5020, which no setting names, is one)."""
    names = sorted(str(p.relative_to(ROOT)) for p in CAPTURES.glob("*eclink_modbus*.pcap")
                   if p.name not in ("eclink_modbus_excerpt.pcap", "eclink_modbus_port5020.pcap"))
    proc = vrshark_report("--json", *names)
    kinds = {c["capture"]: sorted({d["kind"] for d in c["devices"]}) for c in json.loads(proc.stdout)["captures"]}
    assert [n for n, k in kinds.items() if "candidate" in k] == []
    assert sum(k == ["eclink_modbus"] for k in kinds.values()) >= 6
