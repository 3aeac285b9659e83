"""PROFINET frames the capture cut (snaplen), as they come from the field:
a cut frame of a known layout is named as cut, counts as received (its
watchdog or handshake counters, where captured, are supervised), and is
never decoded into values it does not hold; a cut Connect is named as cut,
with what decodes its cyclic frames instead of "no Connect in the capture".
The cut captures are the project's own with frames cut short, their length
on the wire kept (tools/capgen/snaplen.py, editcap -s), so what they hold is
known: every value shown must be the original's, every fault of the original
still found on its frame."""
import json
import os
import subprocess

import pytest

from conftest import CAPTURES, ROOT, expert_infos

PASSES = pytest.mark.parametrize("two_pass", [False, True], ids=["one-pass", "two-pass"])
# cut capture: (original, the cut frames, the protocol, the C-SDU bytes captured, of)
CUT = {
    "snaplen_mcmb2.pcap": ("mcmb2_duplex_watchdog.pcap", range(11, 31), "mcmb2", 24, 40),
    "snaplen_eclink_pnio.pcap": ("eclink_pnio_connect.pcap", range(31, 61), "eclink_pnio", 44, None),
}
VALUES = ["mcmb2.status", "mcmb2.terminal", "mcmb2.uplink_watchdog", "mcmb2.downlink_watchdog", "mcmb2.base_unit",
          "mcmb2.uplink_data", "mcmb2.downlink_data", "mcmb2.watchdog_age", "mcmb2.iops", "eclink.pci", "eclink.cci",
          "eclink.cai", "eclink.bu_state", "eclink.pco", "eclink.cco", "eclink.cao", "eclink.periodic_size",
          "eclink.periodic_data", "eclink.spare", "eclink.ru_battery", "eclink_pnio.pci_age", "eclink_pnio.pco_age"]


def _experts(tshark, capture, two_pass):
    return {(f, name) for f, name, _, _, _, _ in expert_infos(tshark.json(CAPTURES / capture, two_pass=two_pass))}


@PASSES
@pytest.mark.parametrize("cut", sorted(CUT))
def test_cut_frame_named_and_every_fault_still_found(tshark, cut, two_pass):
    original, frames, proto, have, _ = CUT[cut]
    got = _experts(tshark, cut, two_pass)
    assert sorted(f for f, name in got if name == proto + ".cut") == list(frames)
    # every finding of the original on its frame; beside the cut notes only
    # the note that part of an image was decoded
    want = _experts(tshark, original, two_pass)
    assert {e for e in got if e[1] not in (proto + ".cut", "eclink.partial")} == want
    msgs = tshark.frames(CAPTURES / cut, ["_ws.expert.message", "_ws.col.Info"], two_pass=two_pass)
    first = frames[0]
    assert ("only the bytes captured are decoded, the counters from what survived" in
            msgs[first]["_ws.expert.message"])
    assert "C-SDU bytes %d.." % have in msgs[first]["_ws.expert.message"]
    assert "cut by the capture" in msgs[first]["_ws.col.Info"]


@pytest.mark.parametrize("cut", sorted(CUT))
def test_cut_frame_shows_only_values_it_holds(tshark, cut):
    """Each value shown on a cut frame is the original's; the values of
    bytes not captured are absent, not made up."""
    original, frames, proto, _, _ = CUT[cut]
    got = tshark.frames(CAPTURES / cut, VALUES, two_pass=True)
    want = tshark.frames(CAPTURES / original, VALUES, two_pass=True)
    missing = set()
    for f in frames:
        for name in VALUES:
            if got[f][name]:
                assert got[f][name] == want[f][name], (f, name)
            elif want[f][name]:
                missing.add(name)
    # what sits beyond the bytes captured
    if proto == "mcmb2":
        assert missing == {"mcmb2.uplink_data"}
        assert all(got[f]["mcmb2.uplink_watchdog"] or got[f]["mcmb2.downlink_watchdog"] for f in frames)
    else:
        assert missing == {"eclink.periodic_data", "eclink.spare"}
        assert all(got[f]["eclink.pci"] or got[f]["eclink.pco"] for f in frames)


def _editcap_s(capture, snaplen, folder):
    out = folder / ("s%d-%s" % (snaplen, capture))
    subprocess.run(["editcap", "-s", str(snaplen), str(CAPTURES / capture), str(out)], check=True)
    out.chmod(0o644)
    return out


@PASSES
@pytest.mark.parametrize("snaplen,what,cut", [
    (96, "PNIO-CM request cut by the capture at 96 of 774 bytes (snaplen), before its operation number", [1, 2]),
    # (the 200-byte response is whole)
    (200, "Connect request cut by the capture at 200 of 774 bytes (snaplen)", [1])])
def test_cut_connect_named_with_what_decodes(tshark, work_dir, snaplen, what, cut, two_pass):
    cap = _editcap_s("mcmb2_duplex_connect.pcap", snaplen, work_dir)
    got = tshark.frames(cap, ["_ws.expert.message", "mcmb2.connect_cut", "mcmb2.layout.inferred", "mcmb2.status"],
                        two_pass=two_pass)
    assert [f for f, v in got.items() if v["mcmb2.connect_cut"]] == cut
    assert got[1]["_ws.expert.message"] == (
        what + ": its layout cannot be read; the cyclic frames are decoded by the layout inferred from them, or by "
        "their mcmb2.layouts entry")
    inferred = [f for f, v in got.items() if v["mcmb2.layout.inferred"]]
    assert inferred == [8]
    assert "no Connect read: the capture cut the PNIO-CM datagram in frame 1" in got[8]["_ws.expert.message"]
    assert not [f for f, v in got.items() if "no Connect in the capture" in v["_ws.expert.message"]]
    # the cyclic frames decoded as from the Connect (two passes: from the first)
    want = tshark.frames(CAPTURES / "mcmb2_duplex_connect.pcap", ["mcmb2.status"], two_pass=True)
    for f in range(8 if not two_pass else 3, len(want) + 1):
        assert got[f]["mcmb2.status"] == want[f]["mcmb2.status"], f


def test_cut_at_every_length_never_made_up(tshark, work_dir):
    """mcmb2_duplex_connect with its layout from the Connect, the cyclic
    frames cut at every length: a value shown is always the original's."""
    from tools.capgen import profinet
    from tools.capgen.snaplen import snapped
    names = ["mcmb2.status", "mcmb2.uplink_watchdog", "mcmb2.downlink_watchdog", "mcmb2.base_unit",
             "mcmb2.uplink_data", "mcmb2.downlink_data"]
    want = tshark.frames(CAPTURES / "mcmb2_duplex_connect.pcap", names, two_pass=True)
    for snaplen in range(16, 64, 3):
        cap = work_dir / ("every-%d.pcap" % snaplen)
        cap.write_bytes(snapped(profinet.duplex_connect(), snaplen, set(range(3, 40))).to_bytes())
        cap.chmod(0o644)
        got = tshark.frames(cap, names + ["mcmb2.cut"], two_pass=True)
        for f, v in got.items():
            for name in names:
                if v[name]:
                    assert v[name] == want[f][name], (snaplen, f, name)


def test_cut_frame_of_another_sender_left_to_pn_rt(tshark, work_dir):
    """A cut frame with one of our FrameIDs from another station is not
    ours: Wireshark's PN-RT reports the cut, nothing is decoded."""
    from tools.capgen import profinet
    from tools.capgen.snaplen import snapped
    cap = snapped(profinet.duplex_watchdog(), 40, set(range(11, 31)))
    ts, data, orig_len = cap.records[10]                  # frame 11, an uplink
    cap.records[10] = (ts, data[:6] + bytes.fromhex("020000000099") + data[12:], orig_len)
    path = work_dir / "other-sender.pcap"
    path.write_bytes(cap.to_bytes())
    path.chmod(0o644)
    for two_pass in (False, True):
        got = tshark.frames(path, ["_ws.col.Protocol", "mcmb2.cut", "mcmb2.uplink_watchdog"], two_pass=two_pass)
        assert got[11] == {"_ws.col.Protocol": "PN-RT", "mcmb2.cut": "", "mcmb2.uplink_watchdog": ""}
        assert got[13]["mcmb2.cut"] and got[13]["mcmb2.uplink_watchdog"] == "5"


def test_report_names_the_cut_connect(conf_dir):
    """vrshark-report: the layout inferred because the capture cut the
    Connect says so (and where), not "no Connect"."""
    env = dict(os.environ, TZ="UTC", LC_ALL="C.UTF-8", WIRESHARK_CONFIG_DIR=str(conf_dir))
    proc = subprocess.run([str(ROOT / "tools" / "vrshark-report"), "--json", "captures/snaplen_connect.pcap"],
                          env=env, cwd=str(ROOT), capture_output=True, text=True, timeout=600)
    timeline = json.loads(proc.stdout)["captures"][0]["timeline"]
    inferred = [e["text"] for e in timeline if e["field"] == "mcmb2.layout.inferred"]
    assert inferred == ["layout inferred from the cyclic frames (the capture cut the Connect in frame 1: snaplen)"]


@pytest.mark.parametrize("system, layouts, frame, short", [
    ("mcmb2", "0xC010=duplex:40", 1, "C-SDU has 40 bytes, the layout needs 50"),
    ("eclink_pnio", "0xC020/0xC021=eclink:/224", 2, "C-SDU has 40 bytes, the layout needs 230"),
], ids=["mcmb2", "eclink_pnio"])
def test_cut_frame_too_short_for_its_layout(tshark, work_dir, system, layouts, frame, short):
    """A frame the capture cut whose layout (here the table's) needs more
    than the frame has on the wire: both notes, the rest of the capture
    decoded, no Lua Error, in one pass and two."""
    from tools.capgen import profinet
    from tools.capgen.snaplen import snapped
    gen = profinet.duplex_noconnect if system == "mcmb2" else profinet.eclink_noconnect
    cap = snapped(gen(), 24, {1, 2})
    path = work_dir / ("short-cut-%s.pcap" % system)
    path.write_bytes(cap.to_bytes())
    path.chmod(0o644)
    for two_pass in (False, True):
        got = tshark.frames(path, ["_ws.expert.message", "%s.cut" % system], prefs={"mcmb2.layouts": layouts},
                            two_pass=two_pass)
        msgs = got[frame]["_ws.expert.message"]
        assert "Lua Error" not in " ".join(v["_ws.expert.message"] for v in got.values())
        assert got[frame]["%s.cut" % system] and "Cut by the capture at 24 of its" in msgs, msgs
        assert short in msgs


def cut_frames(path, out, frames, snaplen=30):
    """The pcap `path` with `frames` (numbers) cut to `snaplen` bytes, their
    length on the wire kept (as editcap -s does to every frame)."""
    import struct
    data = path.read_bytes()
    res, off, n = bytearray(data[:24]), 24, 0
    while off < len(data):
        sec, usec, incl, orig = struct.unpack("<IIII", data[off:off + 16])
        body = data[off + 16:off + 16 + incl]
        off, n = off + 16 + incl, n + 1
        if n in frames:
            body = body[:snaplen]
        res += struct.pack("<IIII", sec, usec, len(body), orig) + body
    out.write_bytes(bytes(res))
    out.chmod(0o644)
    return out


NOTE_FIELDS = ["_ws.col.Protocol", "mcmb2.candidate_setting", "_ws.expert.message", "mcmb2.cut"]


def test_cut_before_the_layout_was_inferred(tshark, work_dir):
    """Frames the capture cut before the cyclic frames settled their layout
    (no Connect): a cut frame never decides a layout, so they are not
    decoded, but with -2 they say so and offer the entry that decodes them;
    that entry decodes them as cut frames. (In one pass nothing is known of
    them yet: Wireshark's PN-RT reports the cut.)"""
    from test_pnio_reopen import stepping_captures
    _, without = stepping_captures(work_dir, name="cutfirst", order=lambda direction, elements: elements, pairs=200)
    path = cut_frames(without, work_dir / "cut-first.pcap", {1, 2})
    entry = "0x8441/0x8442=duplex:2/2@2"
    got = tshark.frames(path, NOTE_FIELDS, two_pass=True)
    for n, name in ((1, "uplink"), (2, "downlink")):
        assert got[n] == {"_ws.col.Protocol": "PN-RT", "mcmb2.candidate_setting": "mcmb2.layouts:" + entry,
                          "mcmb2.cut": "", "_ws.expert.message": (
                              "Not decoded: cut by the capture at 30 of 60 bytes before the layout of this %s was "
                              "inferred (frames 3..102); to decode it: mcmb2.layouts:%s" % (name, entry))}
    once = tshark.frames(path, NOTE_FIELDS)
    assert once[1] == {"_ws.col.Protocol": "PN-RT", "mcmb2.candidate_setting": "", "mcmb2.cut": "",
                       "_ws.expert.message": ""}
    pinned = tshark.frames(path, NOTE_FIELDS + ["mcmb2.uplink_watchdog"], prefs={"mcmb2.layouts": entry})
    assert pinned[1]["_ws.col.Protocol"] == "MC-MB2" and pinned[1]["mcmb2.cut"]
    assert pinned[1]["mcmb2.uplink_watchdog"] == "0"


@pytest.mark.parametrize("two_pass", [False, True], ids=["one-pass", "two-pass"])
def test_cut_frame_of_a_direction_its_connect_does_not_describe(tshark, work_dir, two_pass):
    """A cut frame of a direction whose Connect could not be learned gets
    the same note as its whole frames: the setting that decodes it."""
    from test_pnio_connect_stray import capture
    path = cut_frames(capture(work_dir, "out", 4), work_dir / "stray-cut.pcap", {4})
    got = tshark.frames(path, NOTE_FIELDS, two_pass=two_pass)
    assert got[4]["_ws.col.Protocol"] == "PN-RT" and got[4]["mcmb2.candidate_setting"] == "mcmb2.layouts"
    assert got[4]["_ws.expert.message"].startswith(
        "Not decoded: the Connect of an MC-MB2-PN duplex/simplex base does not describe this downlink (")
    assert got[6]["_ws.expert.message"] == got[4]["_ws.expert.message"]
