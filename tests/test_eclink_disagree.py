"""EC-Link input images whose fields contradict each other, or whose links
report a fault (TS-0007 6.1, 6.1.1-6.1.3, 9): the cases EG-Link's VRPI has
(tests/test_eglink_disagree.py), each an input image of an armed BU alone
between healthy ones, in scapy-built PROFINET cyclic frames after their
Connect. Each gets its own warning naming both fields and their values
(eclink.fields_disagree) or the link and what its status means
(eclink.link_status.fault), in one pass and with -2.
"""
import shutil

import pytest

from conftest import _world_dir, expert_infos
from pnio_testlib import CaptureFile, Device, eclink_submodules, mac

NEW = ("eclink.fields_disagree", "eclink.link_status.fault")
DISAGREE, FAULT = NEW
CYCLE = 0.03


def input_image(pci, over):
    """An armed BU (RU 0xbeef Enabled), links operational; over: {offset: value}."""
    img = bytearray(64)
    img[0] = pci & 0xFF
    img[20:26] = bytes([0x11, 1, 0, 1, 1, 1])
    img[26:28] = (0xBEEF).to_bytes(2, "big")
    img[28:31] = bytes([3, 80, 90])
    for off, value in over.items():
        img[off] = value
    return bytes(img)


def output_image(pco):
    img = bytearray(224)
    img[0] = pco & 0xFF
    img[20:22] = (10).to_bytes(2, "big")
    return bytes(img)


# (input image bytes changed: {offset: value}, the findings of that image)
CASES = [
    ({33: 1}, [(DISAGREE, "RU state Enabled (3) but RU disabled Disabled (tilting) (1): an enabled RU is not "
                          "disabled")]),
    ({28: 2}, [(DISAGREE, "RU state Armed (2) but RU disabled Enabled (0): Armed means movements are disabled, "
                          "by tilting or inactivity")]),
    ({28: 0, 29: 0, 30: 0}, [(DISAGREE, "Armed RU 0xbeef but RU state Initial (0): Initial means no RU is armed "
                                        "yet")]),
    ({20: 0x10}, [(DISAGREE, "BU state Disarmed (0x10) but Armed RU 0xbeef: a disarmed BU is armed against no "
                             "RU")]),
    ({26: 0, 27: 0, 28: 0, 29: 0, 30: 0},
     [(DISAGREE, "BU state Armed (0x11) but Armed RU 0: in that state the BU is armed against an RU")]),
    ({20: 0x01}, [(DISAGREE, "BU state Stopped (0x01) but RU state Enabled (3): the BU stops when its RU "
                             "signals stop (RU state Stopped)")]),
    ({23: 2}, [(FAULT, "EG-Link status No link (2): the link is not operating: no valid data has been "
                       "received")]),
    ({24: 5}, [(FAULT, "EC-Link status Data error (5): the link is up, but the data exchanged is in error"),
               (DISAGREE, "EC-Link status Data error (5) but BU state Armed (0x11): an EC-Link error holds the "
                          "BU in Initial")]),
    ({25: 4}, [(FAULT, "C-Link status Interface error (4): the link's interface module reports an error")]),
    # TS-0007 9: an EC-Link error with the BU held in Initial is no contradiction, only the fault
    ({20: 0x00, 24: 3, 26: 0, 27: 0, 28: 0, 29: 0, 30: 0},
     [(FAULT, "EC-Link status Link error (3): a configuration error keeps the link from operating")]),
]


@pytest.fixture(scope="module")
def pnio_contradictions():
    """Frames 1-2 the Connect; then per cycle an input, an output frame: a healthy
    input image, each case followed by a healthy one."""
    d = Device(eclink_submodules(4, 224), mac(0x55), 0x8055, 0x8056)
    cap = CaptureFile()
    for p in d.connect():
        cap.add(p)
    images = [{}]
    for over, _ in CASES:
        images += [over, {}]
    for i, over in enumerate(images):
        cap.add(d.cyclic("in", {1: input_image(i, over)}), CYCLE - 0.001 if i else 0.001)
        cap.add(d.cyclic("out", {2: output_image(i)}), 0.001)
    folder = _world_dir("vrshark-eclink-disagree-", 0o755)    # (tshark may run as nobody)
    path = cap.write(folder / "contradictions.pcap")
    path.chmod(0o644)
    yield path
    shutil.rmtree(folder, ignore_errors=True)


def _new_findings(tshark, capture, two_pass):
    out = {}
    for frame, name, severity, _, message, _ in expert_infos(tshark.json(capture, two_pass=two_pass)):
        if name in NEW:
            out.setdefault(frame, []).append((name, message, severity))
    return out


@pytest.mark.parametrize("two_pass", [False, True])
def test_each_contradiction_its_own_warning(tshark, pnio_contradictions, two_pass):
    # input frames: 3 (healthy), then a case every 4 frames from 5 on
    warning = "6291456"
    want = {5 + 4 * i: [(n, m, warning) for n, m in found] for i, (_, found) in enumerate(CASES)}
    assert _new_findings(tshark, pnio_contradictions, two_pass) == want


def test_each_kind_filters_alone(tshark, pnio_contradictions):
    assert sorted(tshark.frames(pnio_contradictions, [], display_filter="eclink.fields_disagree")) == \
        [5, 9, 13, 17, 21, 25, 33]
    assert sorted(tshark.frames(pnio_contradictions, [], display_filter="eclink.link_status.fault")) == \
        [29, 33, 37, 41]
