"""EC-Link over PROFINET in the BU's other operational modes, with traffic
built by scapy's PROFINET layers (tests/pnio_testlib.py), not by the
capture generator.

TS-0007 section 2.1: Input Only (inputs only), Input + Commands (inputs and
commands), Standard (inputs, commands and periodic data). Section 4.3: the
PROFINET modules, slot 1 "Inputs" (64 bytes) and, in slot 2, nothing (Input
Only), "Command Outputs" (20 bytes) or "Standard Outputs" (224). Section 4.1,
the getting-started guide, skips step 5 "update PCO" in Input + Commands
mode (and steps 4, 5, 7, 8 in Input Only); section 8.4 puts the PCO
monitoring with the periodic output data, which Input + Commands does not
carry. vrshark reads this as: no PCO supervision in Input + Commands mode
(a note naming the mode, once), and the layout recognised from what the
mode moves (the input image's PCI; the command counters when commands
flow), never from a PCO the controller need not touch.

The controller here never touches PCO (0 throughout). Over 5 s the BU's
RU sends a command (CCI 0 -> 1 at cycle 8, the controller echoes it in CAO
at cycle 10) and the controller sends one (CCO 0 -> 1 at cycle 20, the BU
echoes it in CAI at cycle 21). Each with the Connect and without it, for
the usual frame order and two others controllers use.
"""
import pytest

from conftest import assert_fields
from pnio_testlib import CaptureFile, Device, data_first, eclink_submodules, iocs_first, mac

CYCLE = 0.125
CYCLES = 40
FIELDS = ["eclink.image", "eclink.pci", "eclink.cci", "eclink.cai", "eclink.pco", "eclink.cco", "eclink.cao",
          "eclink.periodic_size", "eclink_pnio.pco_age", "eclink_pnio.pci_age", "_ws.col.Info", "_ws.expert.message"]
HANDSHAKE = ["eclink_pnio.pco_stalled", "eclink_pnio.pci_stalled", "eclink_pnio.commands_mode",
             "eclink_pnio.cmd_from_ru", "eclink_pnio.cmd_from_ru.ack", "eclink_pnio.cmd_to_ru",
             "eclink_pnio.cmd_to_ru.ack", "eclink_pnio.cmd_from_ru.late", "eclink_pnio.cmd_to_ru.late"]
ORDERS = {"slot_order": None, "pcworx": iocs_first,
          "up_iocs_first_down_data_first": lambda d, e: iocs_first(d, e) if d == "in" else data_first(d, e)}


def input_image(pci, cci, cai):
    img = bytearray(64)
    img[0:4] = bytes([pci & 0xFF, cci, 0, cai])
    img[4:20] = b"FROM-RU-COMMAND!"
    img[20:26] = bytes([0x11, 1, 0, 1, 1, 1])            # Armed; EG-, EC-, C-Link operational
    img[26:28] = (0x4242).to_bytes(2, "big")
    img[28:34] = bytes([3, 80, 90, 0, 0, 0])             # Enabled
    img[58] = 42
    return bytes(img)


def output_image(cco, cao):
    """Input + Commands: 20 bytes, PCO and PAO 0 (never touched)."""
    return bytes([0, cco, 0, cao]) + b"TO-RU-COMMAND-16"


def traffic(outlen, order, connect, work_dir, name):
    """(capture path, frame number of the first cyclic frame)."""
    d = Device(eclink_submodules(4, outlen), mac(0x40 + outlen), 0x8040 + outlen, 0x8041 + outlen,
               order=ORDERS[order])
    cap = CaptureFile()
    if connect:
        for p in d.connect():
            cap.add(p)
    for i in range(CYCLES):
        # (Input Only transfers no commands, section 2.1: CCI and CAI stay)
        cci = 1 if i >= 8 and outlen else 0
        cao = 1 if i >= 10 else 0
        cco = 1 if i >= 20 else 0
        cai = 1 if i >= 21 and outlen else 0
        cap.add(d.cyclic("in", {1: input_image(i, cci, cai)}), CYCLE - 0.001 if i else 0.001)
        cap.add(d.cyclic("out", {2: output_image(cco, cao)} if outlen else {}), 0.001)
    path = cap.write(work_dir / ("%s_%s_%s.pcap" % (name, order, "connect" if connect else "noconnect")))
    return path, 3 if connect else 1


def up(first, i):
    return first + 2 * i


def down(first, i):
    return first + 2 * i + 1


def handshake_findings(tshark, cap, two_pass):
    got = tshark.frames(cap, HANDSHAKE, two_pass=two_pass, display_filter=" || ".join(HANDSHAKE))
    return {n: sorted(k for k in HANDSHAKE if f[k]) for n, f in got.items()}


SOURCES = [pytest.param(True, False, id="connect-one-pass"), pytest.param(True, True, id="connect-two-pass"),
           pytest.param(False, True, id="inferred-two-pass")]


@pytest.mark.parametrize("order", list(ORDERS))
@pytest.mark.parametrize("connect,two_pass", SOURCES)
def test_input_and_commands_mode(tshark, work_dir, order, connect, two_pass):
    cap, first = traffic(20, order, connect, work_dir, "commands")
    got = tshark.frames(cap, FIELDS, two_pass=two_pass)
    cyclic = [n for n in got if n >= first]
    # every cyclic frame decodes, inputs and outputs alternating
    assert [got[n]["eclink.image"] for n in cyclic] == ["input", "output"] * CYCLES
    # no PCO stall (PCO stands 5 s), no PCO age: not supervised in this mode
    assert not any("PCO 0 has not changed" in got[n]["_ws.expert.message"] or got[n]["eclink_pnio.pco_age"]
                   for n in cyclic)
    assert_fields(got[down(first, 30)], {"eclink.pco": 0, "eclink.cco": 1, "eclink.cao": 1,
                                         "eclink.periodic_size": None, "eclink_pnio.pco_age": None,
                                         "_ws.col.Info": "Output image PCO=0 CCO=1 CAO=1"})
    want = {down(first, 0): ["eclink_pnio.commands_mode"],
            up(first, 8): ["eclink_pnio.cmd_from_ru"], down(first, 10): ["eclink_pnio.cmd_from_ru.ack"],
            down(first, 20): ["eclink_pnio.cmd_to_ru"], up(first, 21): ["eclink_pnio.cmd_to_ru.ack"]}
    assert handshake_findings(tshark, cap, two_pass) == want
    assert "Input + Commands mode (20-byte output image): no periodic data, so PCO is not supervised " \
        "(TS-0007 2.1, 8.4)" in got[down(first, 0)]["_ws.expert.message"]


@pytest.mark.parametrize("order", list(ORDERS))
def test_input_and_commands_mode_inferred_in_one_pass(tshark, work_dir, order):
    """Without the Connect, one pass decodes from the frame the layout is
    inferred in, a few frames in (the input image's PCI chain), not never."""
    cap, _ = traffic(20, order, False, work_dir, "commands1")
    got = tshark.frames(cap, ["eclink.image", "eclink_pnio.layout_entry", "eclink_pnio.pco_stalled"])
    decoded = [n for n in got if got[n]["eclink.image"]]
    assert decoded and min(decoded) <= 12 and decoded == list(range(min(decoded), 2 * CYCLES + 1))
    entries = {got[n]["eclink_pnio.layout_entry"] for n in decoded}
    assert len(entries) == 1 and entries.pop().startswith("0x8054/0x8055=eclink:/20@4")
    assert not any(f["eclink_pnio.pco_stalled"] for f in got.values())


@pytest.mark.parametrize("order", list(ORDERS))
@pytest.mark.parametrize("connect,two_pass", SOURCES)
def test_input_only_mode(tshark, work_dir, order, connect, two_pass):
    """No output image at all: the output CR carries the IOCS only. Every
    input frame decodes; the handshake has nothing of the controller's to
    supervise, and says nothing of PCO."""
    cap, first = traffic(0, order, connect, work_dir, "inputonly")
    got = tshark.frames(cap, FIELDS + ["eclink_pnio.layout"], two_pass=two_pass)
    assert [got[n]["eclink.image"] for n in got if n >= first] == ["input", ""] * CYCLES
    assert_fields(got[up(first, 30)], {"eclink.pci": 30, "eclink.cci": 0, "eclink.cai": 0,
                                       "eclink_pnio.pci_age": "0.000000000", "eclink.pco": None})
    if not connect:
        assert got[up(first, 30)]["eclink_pnio.layout"].startswith("inferred from cyclic frames")
    assert handshake_findings(tshark, cap, two_pass) == {}
    assert not any(got[n]["_ws.expert.message"] for n in got if n >= first and "layout inferred" not in
                   got[n]["_ws.expert.message"])
