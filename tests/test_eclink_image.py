"""EC-Link raw images (the "eclink" dissector on a user link-layer type), as a
Profibus DP user decodes a hex dump: text2pcap -l 147, then tshark with a
user_dlts entry."""
import os
import struct
import subprocess

import pytest

from conftest import assert_fields

USER_DLT = 'uat:user_dlts:"User 0 (DLT=147)","eclink","0","","0",""'


def input_image(**over):
    img = bytearray(64)
    img[0:4] = bytes([5, 2, 1, 9])
    img[20:26] = bytes([0x11, 1, 2, 1, 1, 1])
    img[26:28] = struct.pack(">H", 0x1234)
    img[28:34] = bytes([3, 80, 90, 1, 0, 0])
    img[34:42] = struct.pack(">4h", 500, -250, 0, 1000)
    img[42:58] = struct.pack(">8h", 1, -1, 0, 3, 0, 0, 0, 1000)
    img[58:60] = bytes([200, 1])
    for off, val in over.items():
        img[int(off[1:])] = val
    return bytes(img)


def output_image(size=300, block=1, spare=0, std=True):
    img = bytearray(224 if std else 20)
    img[0:4] = bytes([7, 8, 0, 3])
    img[4:20] = b"HELLO-RU".ljust(16, b"\0")
    if std:
        img[20:24] = struct.pack(">HBB", size, block, spare)
        img[24:224] = bytes(i & 0xFF for i in range(200))
    return bytes(img)


@pytest.fixture
def raw_capture(work_dir):
    def make(*images):
        txt = work_dir / "images.txt"
        txt.write_text("".join("0000 " + " ".join("%02x" % b for b in img) + "\n" for img in images))
        pcap = work_dir / "images.pcap"
        subprocess.run(["text2pcap", "-q", "-l", "147", str(txt), str(pcap)], check=True)
        pcap.chmod(0o644)
        return pcap
    return make


def test_input_image_fields(tshark, raw_capture):
    cap = raw_capture(input_image())
    tshark.expect(cap, 1, {
        "eclink.image": "input", "eclink.pci": 5, "eclink.cci": 2, "eclink.pai": 1, "eclink.cai": 9,
        "eclink.bu_state": "0x11", "eclink.es_relays_open": 0, "eclink.vlaps": 1, "eclink.unarmed_rus": 2,
        "eclink.eg_link_status": 1, "eclink.ec_link_status": 1, "eclink.c_link_status": 1,
        "eclink.armed_ru": "0x1234", "eclink.ru_state": 3, "eclink.ru_battery": 80, "eclink.ru_rssi": 90,
        "eclink.ru_cable": 1, "eclink.ru_docked": 0, "eclink.ru_disabled": 0,
        "eclink.joystick1": 500, "eclink.joystick2": -250, "eclink.joystick3": 0, "eclink.joystick4": 1000,
        "eclink.switch1": 1, "eclink.switch2": -1, "eclink.switch4": 3, "eclink.switch8": 1000,
        "eclink.encoder": 200, "eclink.encoder_switch": 1, "eclink.spare": "00000000",
        "eclink.cmd_from_ru": "00000000000000000000000000000000",
        "_ws.col.Info": "Input image PCI=5 CCI=2 BU=Armed RU 0x1234=Enabled",
    }, extra=["-o", USER_DLT])
    assert tshark.experts(cap, extra=["-o", USER_DLT]) == {}


def test_input_tree_reads_like_eglink(tshark, raw_capture):
    """Armed RU in hex, percentages with a space, undefined values as
    Unknown (0x42), the relay state right after the BU state."""
    cap = raw_capture(input_image(b20=0x05, b28=7))
    tree = tshark.verbose(cap, extra=["-o", USER_DLT])
    lines = [line.strip() for line in tree.splitlines()]
    bu = lines.index("BU state: Unknown (0x05)")
    assert lines[bu + 1].startswith("[Expert Info (Error/Protocol): BU state Unknown (0x05)")
    # the next item beside the BU state (its expert info is under it)
    indent = next(len(x) - len(x.lstrip()) for x in tree.splitlines() if x.strip() == lines[bu])
    siblings = [x.strip() for x in tree.splitlines() if len(x) - len(x.lstrip()) == indent]
    assert siblings[siblings.index("BU state: Unknown (0x05)") + 1] == "[ES-Link relays open: Yes (BU state below 0x10, or RU state Stopped)]"
    assert "Armed RU: 0x1234" in lines and "RU battery: 80 %" in lines
    assert "RU state: Unknown (0x07)" in lines
    assert tshark.field(cap, "_ws.col.Info", extra=["-o", USER_DLT]) == [
        "Input image PCI=5 CCI=2 BU=Unknown (0x05) RU 0x1234=Unknown (0x07) [relays open] [undefined]"]


def test_output_images(tshark, raw_capture):
    cap = raw_capture(output_image(), output_image(std=False))
    names = ["eclink.image", "eclink.pco", "eclink.cco", "eclink.pao", "eclink.cao", "eclink.cmd_to_ru",
             "eclink.periodic_size", "eclink.periodic_block", "eclink.spare", "eclink.periodic_data"]
    got = tshark.frames(cap, names, extra=["-o", USER_DLT])
    common = {"eclink.image": "output", "eclink.pco": 7, "eclink.cco": 8, "eclink.pao": 0, "eclink.cao": 3,
              "eclink.cmd_to_ru": "48454c4c4f2d52550000000000000000"}
    assert_fields(got[1], dict(common, **{"eclink.periodic_size": 300, "eclink.periodic_block": 1,
                                          "eclink.spare": "00", "eclink.periodic_data": bytes(range(200)).hex()}),
                  "frame 1 (224 bytes)")
    assert_fields(got[2], dict(common, **{"eclink.periodic_size": None, "eclink.periodic_block": None,
                                          "eclink.spare": None, "eclink.periodic_data": None}),
                  "frame 2 (20 bytes)")


def test_input_checks(tshark, raw_capture):
    bad = input_image(b20=0x03, b21=4, b23=7, b28=5, b29=101, b30=150, b31=2, b33=4, b34=0x03,
                      b35=0xE9, b59=2, b61=1)
    stopped = input_image(b28=4)
    unarmed = input_image(b26=0, b27=0)
    cap = raw_capture(bad, stopped, unarmed)
    exp = tshark.experts(cap, extra=["-o", USER_DLT])
    assert exp[1] == [
        "ES-Link relays open: BU state Blocked (0x03)",
        "4 VLAPs reported: a BU has at most 3",
        "EG-Link status Unknown (0x07): defined are 0..6",
        "RU state Unknown (0x05): defined are 0..4",
        "RU battery 101 % is above 100 %",
        "RU C-Link RSSI 150 % is above 100 %",
        "RU cable Unknown (0x02): only 0 and 1 are defined",
        "RU disabled reason Unknown (0x04): defined are 0 enabled, 1 tilted, 2 inactivity, 3 other",
        "Joystick 1 position 1001 is outside -1000..+1000",
        "Encoder switch Unknown (0x02): only 0 and 1 are defined",
        "Spare bytes 60..63 are not 0",
    ]
    # severity and group as in every vrshark protocol (docs/findings.md "How findings read")
    # relays open / RU stopped: warning, Response code; undefined or out of range: error, Protocol;
    # spare not 0: warning, Protocol
    kinds = {"eclink.relays_open": ("6291456", "50331648"), "eclink.ru_stopped": ("6291456", "50331648"),
             "eclink.vlaps.range": ("8388608", "150994944"), "eclink.ru_state.range": ("8388608", "150994944"),
             "eclink.percent.range": ("8388608", "150994944"), "eclink.bool.range": ("8388608", "150994944"),
             "eclink.unarmed_not_zero": ("8388608", "150994944"), "eclink.spare.not_zero": ("6291456", "150994944")}
    for name, (severity, group) in kinds.items():
        frames = tshark.frames(cap, ["_ws.expert.severity", "_ws.expert.group", "_ws.expert.message"],
                               display_filter=name, extra=["-o", USER_DLT])
        assert frames, name
        for n, r in frames.items():
            # the finding of that expert field among the frame's findings
            pairs = list(zip(r["_ws.expert.severity"].split(","), r["_ws.expert.group"].split(",")))
            assert (severity, group) in pairs, (name, n, pairs)
    assert exp[2] == ["RU stopped: ES-Link relays open"]
    # (TS-0007 6.1.1: an Armed BU is armed against an RU: the BU state disagrees with Armed RU 0)
    assert exp[3][0] == "BU state Armed (0x11) but Armed RU 0: in that state the BU is armed against an RU"
    assert "Armed RU is 0 but RU state is not 0" in exp[3]
    assert "Armed RU is 0 but Joystick 1 is not 0" in exp[3]
    relays = tshark.frames(cap, ["eclink.es_relays_open"], extra=["-o", USER_DLT])
    assert_fields(relays[1], {"eclink.es_relays_open": 1})
    # TS-0007 6.1.3, RU state 4 "Stopped": the armed remote has stopped, the ES-Link relay opens
    # (BU state Armed 0x11 on this frame)
    assert_fields(relays[2], {"eclink.es_relays_open": 1})
    assert_fields(relays[3], {"eclink.es_relays_open": 0})
    assert list(tshark.frames(cap, [], display_filter="eclink.es_relays_open == 1",
                              extra=["-o", USER_DLT])) == [1, 2]


def test_output_checks(tshark, raw_capture):
    cap = raw_capture(output_image(size=60000, block=0, spare=5), output_image(size=150, block=1),
                      output_image(size=51200, block=255))
    exp = tshark.experts(cap, extra=["-o", USER_DLT])
    assert exp[1] == ["Periodic data size 60000 is over 51200", "Spare byte 23 is 0x05, not 0"]
    assert exp[2] == ["Periodic data block 1 is beyond the periodic data size 150 (blocks 0..0)"]
    assert 3 not in exp


def test_checks_kept_by_the_bytes_they_read(tshark, raw_capture):
    """The findings of an image are kept by the bytes the checks read (20 on:
    the counters before them move on every cycle): an image that differs in
    the counters alone gets the same findings and its own summary, one that
    differs in a checked byte its own findings."""
    blocked = input_image(b20=0x03)
    cap = raw_capture(blocked, input_image(b20=0x03, b0=6, b2=2), input_image(b0=6, b2=2),
                      output_image(size=60000), output_image(size=60000)[:4] + b"OTHER-CMD".ljust(16, b"\0")
                      + output_image(size=60000)[20:], bytes([8]) + output_image(size=60000)[1:],
                      bytes([8]) + output_image()[1:])
    exp = tshark.experts(cap, extra=["-o", USER_DLT])
    relays = ["ES-Link relays open: BU state Blocked (0x03)"]
    over = ["Periodic data size 60000 is over 51200"]
    assert exp == {1: relays, 2: relays, 4: over, 5: over, 6: over}
    info = tshark.field(cap, "_ws.col.Info", extra=["-o", USER_DLT])
    assert info == [
        "Input image PCI=5 CCI=2 BU=Blocked RU 0x1234=Enabled [relays open]",
        "Input image PCI=6 CCI=2 BU=Blocked RU 0x1234=Enabled [relays open]",
        "Input image PCI=6 CCI=2 BU=Armed RU 0x1234=Enabled",
        "Output image PCO=7 CCO=8 CAO=3 size=60000 block=1 [undefined]",
        "Output image PCO=7 CCO=8 CAO=3 size=60000 block=1 [undefined]",
        "Output image PCO=8 CCO=8 CAO=3 size=60000 block=1 [undefined]",
        "Output image PCO=8 CCO=8 CAO=3 size=300 block=1",
    ]


def test_bad_length(tshark, raw_capture):
    cap = raw_capture(bytes(10))
    assert tshark.experts(cap, extra=["-o", USER_DLT]) == {
        1: ["10 bytes is not an EC-Link image (input 64, output 20 or 224)"]}
    assert tshark.field(cap, "_ws.col.Info", extra=["-o", USER_DLT]) == ["Not an EC-Link image (10 bytes)"]


SWAP_SCRIPT = r"""
package.path = %(lua)r .. "/?.luam;" .. package.path
local image = require("vrshark.eclink_image")
local out = assert(io.open(%(out)r, "w"))
local bad = 0
for n = 0, 300 do
    local t = {}
    for i = 1, n do t[i] = string.char((i * 151 + n * 7) %% 256) end
    local x = table.concat(t)
    -- the reference: each pair swapped, an odd last byte left
    local want = x:gsub("(.)(.)", "%%2%%1")
    if image.swap_pairs(x) ~= want then
        bad = bad + 1
        out:write("BAD length ", n, "\n")
    end
end
out:write("bad ", bad, "\n")
out:close()
"""


def test_swap_pairs_every_length(lua_probe):
    """Register bytes in image order (the Modbus decoder swaps every image it
    sees, 32 bytes a step): each length from 0 to 300, odd ones included,
    against a gsub of pairs."""
    assert lua_probe(SWAP_SCRIPT) == ["bad 0"]


# (BU state, RU state): Armed and Enabled, Armed and Stopped, Blocked, Stopped BU, Disarmed,
# Armed with the RU Armed (tilted)
RELAY_CASES = [(0x11, 3), (0x11, 4), (0x03, 3), (0x01, 4), (0x10, 0), (0x11, 2)]


@pytest.mark.skipif(bool(os.environ.get("VRSHARK_NO_C_PLUGIN")), reason="EG-Link is the C plugin")
def test_relays_open_one_fact_in_eglink_and_eclink(tshark, raw_capture, work_dir):
    """One fact, one value: the same BU and RU state reads the same
    "ES-Link relays open" in an EG-Link VRPI (eglink.relays_open) and in an
    EC-Link input image (eclink.es_relays_open). TS-0007 6.1.1 (BU state
    below Disarmed) and 6.1.3 (RU state 4, Stopped: the ES-Link relay opens)."""
    from eglink_testlib import gen
    from tools.capgen.pcap import Capture
    link = gen.Link(Capture())
    for i, (bu, ru) in enumerate(RELAY_CASES):
        link.bu(0.125 * i, "VRPI", gen.vrpi(bu_state=bu, armed_ru=0x1234, ru_state=ru, battery=80, rssi=90))
    eg_cap = work_dir / "eglink_relays.pcap"
    eg_cap.write_bytes(link.cap.to_bytes())
    eg_cap.chmod(0o644)
    ec_cap = raw_capture(*(input_image(b20=bu, b28=ru) for bu, ru in RELAY_CASES))
    eg = tshark.frames(eg_cap, ["eglink.relays_open"])
    ec = tshark.frames(ec_cap, ["eclink.es_relays_open"], extra=["-o", USER_DLT])
    want = [1 if bu < 0x10 or ru == 4 else 0 for bu, ru in RELAY_CASES]
    assert [int(eg[n]["eglink.relays_open"]) for n in sorted(eg)] == want
    assert [int(ec[n]["eclink.es_relays_open"]) for n in sorted(ec)] == want
    # the display filters pick the same frames
    assert list(tshark.frames(eg_cap, [], display_filter="eglink.relays_open == 1")) == \
        list(tshark.frames(ec_cap, [], display_filter="eclink.es_relays_open == 1", extra=["-o", USER_DLT]))


def test_passive_and_disarmed(tshark, raw_capture):
    """TS-0007 6.1.2: link status 6, Passive, is reported only on the C-Link
    and only when no remote is armed; 6.1.3: RU state 1, Disarmed, is used
    only inside the BU. Passive elsewhere is a warning (Protocol), RU state 1
    on the wire a note; a disarmed BU's C-Link Passive is neither."""
    allowed = bytearray(64)
    allowed[20:26] = bytes([0x10, 1, 2, 1, 1, 6])             # Disarmed, no RU armed, C-Link Passive
    cap = raw_capture(input_image(b25=6), input_image(b23=6), bytes(allowed), input_image(b28=1))
    exp = tshark.experts(cap, extra=["-o", USER_DLT])
    assert exp[1] == ["C-Link status Passive while RU 0x1234 is armed: Passive only when no remote is armed"]
    assert exp[2] == ["EG-Link status Passive: only the C-Link reports Passive"]
    assert 3 not in exp
    assert exp[4] == ["RU state 1 (Disarmed) on the wire: TS-0007 uses it only inside the BU"]
    for name, frames, severity in (("eclink.link_status.passive", [1, 2], "6291456"),
                                   ("eclink.ru_state.disarmed", [4], "4194304")):
        got = tshark.frames(cap, ["_ws.expert.severity", "_ws.expert.group"], display_filter=name,
                            extra=["-o", USER_DLT])
        assert sorted(got) == frames, name
        for f in frames:
            assert got[f] == {"_ws.expert.severity": severity, "_ws.expert.group": "150994944"}, (name, f)
    tshark.expect(cap, 4, {"eclink.ru_state": 1}, extra=["-o", USER_DLT])
