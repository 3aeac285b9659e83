"""A BU's Modbus/TCP connection whose TCP segments come out of order, as a
mirror port delivers them.

On a project capture: a request sent in two segments, the second captured
first. With Wireshark's default (tcp.reassemble_out_of_order off) TCP hands
the request to no dissector: its response is "without a request", and the
note names the TCP setting that reassembles them; with that setting the
request and its response decode as in the capture sent in order (one pass
and two).

On a real stack's traffic (pymodbus BU and PLC on 127.0.0.1, captured on
lo), cut by scapy: a write and two responses out of order, and a response
whose header came in a segment of its own (in order). Either direction, the
piece TCP hands over from inside an ADU carries the note
eclink_modbus.mid_adu naming the setting, in one pass and with -2, and
vrshark-report carries it; with the setting everything decodes as sent.
"""
import json
import os
import shutil
import subprocess

import pytest
from scapy.all import IP, TCP, rdpcap, wrpcap

import test_eclink_modbus_realstack as rs
from conftest import CAPTURES, ROOT, _world_dir

ORIGINAL = "eclink_modbus_segments.pcap"
REQUEST = 19          # the read of the input image (Trans 6) after the connection is recognised
TEXT = ("Response without a request in the capture: the request was not captured, or its TCP segments came out "
        "of order (TCP Previous segment not captured, Retransmission), which tcp.reassemble_out_of_order:TRUE "
        "reassembles")
NAMES = ["eclink_modbus.no_request", "eclink_modbus.request_in", "eclink.image", "eclink.pci", "eclink.bu_state",
         "modbus.func_code", "_ws.expert.message"]


def _pieces(q, cuts, order, until):
    """The TCP segment q cut at the payload offsets `cuts`, its pieces
    captured in `order` (0: the first), between q's time and `until`."""
    payload = bytes(q[TCP].payload)
    bounds = [0] + list(cuts) + [len(payload)]
    step = (until - q.time) / (len(order) + 1)
    out = []
    for i, k in enumerate(order):
        p = q.copy()
        p[TCP].remove_payload()
        p[TCP].add_payload(payload[bounds[k]:bounds[k + 1]])
        p[TCP].seq = q[TCP].seq + bounds[k]
        del p["IP"].len, p["IP"].chksum, p[TCP].chksum
        p = p.__class__(bytes(p))
        p.time = q.time + i * step
        out.append(p)
    return out


@pytest.fixture(scope="module")
def out_of_order():
    """ORIGINAL with the request of frame REQUEST sent as two segments, the
    second (bytes 6..) captured first: frames REQUEST and REQUEST + 1."""
    pk = rdpcap(str(CAPTURES / ORIGINAL))
    parts = _pieces(pk[REQUEST - 1], (6,), (1, 0), pk[REQUEST].time)
    folder = _world_dir("vrshark-ooo-")
    path = folder / "out-of-order.pcap"
    wrpcap(str(path), list(pk[:REQUEST - 1]) + parts + list(pk[REQUEST:]))
    path.chmod(0o644)
    yield path
    shutil.rmtree(folder, ignore_errors=True)


@pytest.mark.parametrize("two_pass", [False, True], ids=["one-pass", "two-pass"])
def test_default_names_the_tcp_setting(tshark, out_of_order, two_pass):
    got = tshark.frames(out_of_order, NAMES, two_pass=two_pass)
    response = REQUEST + 2
    assert [f for f, v in got.items() if v["eclink_modbus.no_request"]] == [response]
    assert TEXT in got[response]["_ws.expert.message"]
    # no image from a response whose request (its start address) is unknown
    assert not got[response]["eclink.image"]


@pytest.mark.parametrize("two_pass", [False, True], ids=["one-pass", "two-pass"])
def test_with_the_setting_decoded_as_in_order(tshark, out_of_order, two_pass):
    prefs = {"tcp.reassemble_out_of_order": "TRUE"}
    got = tshark.frames(out_of_order, NAMES, prefs=prefs, two_pass=two_pass)
    want = tshark.frames(CAPTURES / ORIGINAL, NAMES, two_pass=two_pass)
    assert not [f for f, v in got.items() if v["eclink_modbus.no_request"]]
    # the reassembled request in the second segment's frame, its response one later
    assert got[REQUEST + 1]["modbus.func_code"] == "4"
    response = got[REQUEST + 2]
    assert response["eclink_modbus.request_in"] == str(REQUEST + 1)
    for name in ("eclink.image", "eclink.pci", "eclink.bu_state"):
        assert response[name] == want[REQUEST + 1][name], name
    # every other frame as in the capture sent in order (one frame later)
    for f in range(REQUEST + 2, len(want) + 1):
        for name in ("eclink.image", "eclink.pci", "eclink.bu_state"):
            assert got[f + 1][name] == want[f][name], (f, name)


@pytest.mark.parametrize("snaplen", [80, 200])
def test_cut_adus_never_decoded_into_values(tshark, work_dir, snaplen):
    """Modbus/TCP cut by the capture (editcap -s): Wireshark names each cut
    frame ("Packet size limited during capture") and TCP reassembles no cut
    segment; every EC-Link value shown is the one sent (at 200 bytes the
    reads are whole, the output writes cut), none from bytes not captured."""
    cut = work_dir / ("s%d.pcap" % snaplen)
    subprocess.run(["editcap", "-s", str(snaplen), str(CAPTURES / "eclink_modbus_basic.pcap"), str(cut)], check=True)
    cut.chmod(0o644)
    names = ["eclink.image", "eclink.pci", "eclink.pco", "eclink.cao", "eclink.bu_state", "eclink.periodic_data"]
    want = tshark.frames(CAPTURES / "eclink_modbus_basic.pcap", names, two_pass=True)
    for two_pass in (False, True):
        got = tshark.frames(cut, names + ["frame.cap_len", "frame.len"], two_pass=two_pass)
        shown = 0
        for f, v in got.items():
            for name in names:
                if v[name]:
                    assert v[name] == want[f][name], (f, name)
                    shown += 1
            if v["frame.cap_len"] != v["frame.len"]:
                assert not v["eclink.image"], f
        assert shown > 0 if snaplen == 200 else shown == 0


# --- a real Modbus/TCP stack's segments out of order, both directions --------------

REAL_PREFS = {"eclink_modbus.port": str(rs.PORT)}
SHOWN = ["eclink.image", "eclink.pci", "eclink.cci", "eclink.pco", "eclink.cao", "eclink.bu_state"]
REAL_NAMES = ["eclink_modbus.mid_adu", "eclink_modbus.no_request", "eclink_modbus.request_in",
              "eclink_modbus.response_in",
              "_ws.expert.message"] + SHOWN
MID_ADU = ("TCP data from inside an ADU, not decoded (%d bytes from the %s): earlier segments not captured, "
           "or out of order (TCP Previous segment not captured, Retransmission), which "
           "tcp.reassemble_out_of_order:TRUE reassembles")


@pytest.fixture(scope="module")
def real_stack():
    """The plant of test_eclink_modbus_realstack: the BU, three ordinary
    servers and an IO device polled like a BU, all on one port."""
    yield from rs.captured()


class Reordered:
    """The real capture with segments out of order, as a mirror port delivers
    them: a write of the output image (controller to BU) cut after its
    header, the image captured first; a read's response (BU to controller)
    cut after its transaction id and length, the rest first; a later
    response in three pieces captured third, first, second; and, in order,
    a response whose MBAP header came in a segment of its own (the rest of
    the ADU in the next), which Wireshark's Modbus/TCP dissector alone never
    joins (it needs 8 bytes to take a segment).
      new_of   {frame of the original: its (first) frame here}
      cut      {original frame cut: (the frame of its first piece, the frame
               of the last, the note the first gets or None)}"""

    def __init__(self, capture):
        pk = rdpcap(str(capture))
        port = rs.PORT
        # (the BU's own: the IO device on 127.0.0.5 is polled the same way)
        reads = [i + 1 for i, p in enumerate(pk) if TCP in p and p[TCP].sport == port and p[IP].src == rs.BU
                 and len(p[TCP].payload) == 73]
        writes = [i + 1 for i, p in enumerate(pk) if TCP in p and p[TCP].dport == port and p[IP].dst == rs.BU
                  and len(p[TCP].payload) == 237]
        assert len(reads) >= 15 and len(writes) >= 15, (len(reads), len(writes))
        self.write, self.read, self.read3, self.head = writes[-8], reads[-6], reads[-3], reads[-10]
        plan = {self.write: ((13,), (1, 0), "controller"), self.read: ((6,), (1, 0), "BU"),
                self.read3: ((6, 40), (2, 0, 1), "BU"), self.head: ((7,), (0, 1), None)}
        out, self.new_of, self.cut = [], {}, {}
        for n, p in enumerate(pk, 1):
            self.new_of[n] = len(out) + 1
            if n in plan:
                cuts, order, sender = plan[n]
                pieces = _pieces(p, cuts, order, pk[n].time)
                size = len(pieces[0][TCP].payload)
                self.cut[n] = (len(out) + 1, len(out) + len(pieces), sender and MID_ADU % (size, sender))
                out += pieces
            else:
                out.append(p)
        self.path = capture.parent / "out-of-order.pcap"
        wrpcap(str(self.path), out)
        self.path.chmod(0o644)


@pytest.fixture(scope="module")
def reordered(real_stack):
    return Reordered(real_stack[0])


@pytest.mark.parametrize("two_pass", [False, True], ids=["one-pass", "two-pass"])
def test_real_stack_default_notes_both_directions(tshark, real_stack, reordered, two_pass):
    """Wireshark's defaults: the piece TCP hands over first (data from inside
    the ADU) carries the note naming the TCP setting, whichever side sent
    it, with its size; the write's response says its request is missing;
    the reads whose responses were cut show no response; the response whose
    header came alone, in order, decoded in the frame of its rest; every
    other frame decodes as in the capture as sent."""
    cap, r = real_stack[0], reordered
    got = tshark.frames(r.path, REAL_NAMES, prefs=REAL_PREFS, two_pass=two_pass)
    want = {first: text for first, _, text in r.cut.values() if text}
    assert sorted(f for f, v in got.items() if v["eclink_modbus.mid_adu"]) == sorted(want)
    for f, text in want.items():
        assert text in got[f]["_ws.expert.message"], f
    for first, last, text in r.cut.values():
        if text:
            assert [got[f]["eclink.image"] for f in range(first, last + 1)] == [""] * (last + 1 - first)
    assert [f for f, v in got.items() if v["eclink_modbus.no_request"]] == [r.new_of[r.write + 1]]
    orig = tshark.frames(cap, REAL_NAMES, prefs=REAL_PREFS, two_pass=two_pass)
    for read in (r.read, r.read3):
        request = int(orig[read]["eclink_modbus.request_in"])
        # (a request names its response once that is known: on a second pass)
        assert orig[request]["eclink_modbus.response_in"] == (str(read) if two_pass else "")
        assert got[r.new_of[request]]["eclink_modbus.response_in"] == ""
    head = r.cut[r.head][1]
    assert got[head]["eclink.image"] == "input"
    for f, v in orig.items():
        if f not in (r.write, r.write + 1, r.read, r.read3):
            assert {k: got[head if f == r.head else r.new_of[f]][k] for k in SHOWN} == {k: v[k] for k in SHOWN}, f


@pytest.mark.parametrize("two_pass", [False, True], ids=["one-pass", "two-pass"])
def test_real_stack_with_the_setting_decoded_as_sent(tshark, real_stack, reordered, two_pass):
    """tcp.reassemble_out_of_order:TRUE: no note; each cut ADU decoded in the
    frame of its last piece with the values of the capture as sent (the
    reads: what the PLC read), every other frame as sent."""
    (cap, log), r = real_stack, reordered
    prefs = dict(REAL_PREFS, **{"tcp.reassemble_out_of_order": "TRUE"})
    got = tshark.frames(r.path, REAL_NAMES, prefs=prefs, two_pass=two_pass)
    assert [f for f, v in got.items() if v["eclink_modbus.mid_adu"] or v["eclink_modbus.no_request"]] == []
    orig = tshark.frames(cap, REAL_NAMES, prefs=REAL_PREFS, two_pass=two_pass)
    at = {f: last for f, (_, last, _) in r.cut.items()}
    for f, v in orig.items():
        assert {k: got[at.get(f, r.new_of[f])][k] for k in SHOWN} == {k: v[k] for k in SHOWN}, f
    # (every read of the PLC decoded: the first ones, before the connection
    # was recognised, on a second pass)
    every = tshark.frames(cap, REAL_NAMES, prefs=REAL_PREFS, two_pass=True)
    reads = [f for f, v in sorted(every.items()) if v["eclink.image"] == "input"]
    assert len(reads) == len(log["read"])
    for read in (r.read, r.read3, r.head):
        regs = log["read"][reads.index(read)]
        v = got[at[read]]
        assert (int(v["eclink.pci"]), int(v["eclink.cci"])) == (regs[0] & 0xFF, regs[0] >> 8)


def _report(*args):
    proc = subprocess.run([str(ROOT / "tools" / "vrshark-report")] + [str(a) for a in args], capture_output=True,
                          text=True, cwd=str(ROOT), stdin=subprocess.DEVNULL, timeout=600,
                          env=dict(os.environ, TZ="UTC", LC_ALL="C.UTF-8"))
    assert proc.returncode in (0, 1), proc.stderr
    return proc


def test_report_carries_the_note(reordered):
    """vrshark-report: the notes in the BU's timeline (a burst: the three
    pieces within a second) beside the response without its request, notes
    as in the dissector; the other servers are no device. --fail-on warn
    does not fail on them (it does on a warning the timing of the run may
    have given, a poll gap), and the text says them; --fail-on note fails."""
    r = reordered
    port = ["-o", "eclink_modbus.port:%d" % rs.PORT]
    got = json.loads(_report("--json", "--fail-on", "warn", *port, r.path).stdout)
    rep = got["captures"][0]
    assert [d["name"] for d in rep["devices"]] == ["EC-Link BU, Modbus/TCP server %s:%d" % (rs.BU, rs.PORT)]
    noted = sorted(first for first, _, text in r.cut.values() if text)
    tcp = [e for e in rep["timeline"] if e["field"] in ("eclink_modbus.mid_adu", "eclink_modbus.no_request")]
    assert [(e["frame"], e["severity"], e["field"], e["count"], e["last_frame"]) for e in tcp] == [
        (noted[0], "note", "eclink_modbus.mid_adu", 3, noted[-1]),
        (r.new_of[r.write + 1], "note", "eclink_modbus.no_request", 1, r.new_of[r.write + 1])]
    warned = [e for e in rep["timeline"] if e["severity"] != "note"]
    assert got["exit_status"] == (1 if warned else 0), warned
    text = _report("--fail-on", "warn", *port, r.path)
    assert ("%d  note      [1]  TCP data from inside an ADU not decoded: segments out of order or not captured "
            "(3x, frames %d-%d" % (noted[0], noted[0], noted[-1])) in text.stdout
    failed = _report("--fail-on", "note", *port, r.path)
    assert failed.returncode == 1
