"""EC-Link over Modbus/TCP detection: the heuristic, the detection
preference, and no false positives on ordinary Modbus traffic."""
import os
import re
import subprocess
from pathlib import Path

import pytest

from conftest import CAPTURES


def test_late_accept(tshark, capture_file):
    """Transactions before the first valid input image stay plain Modbus, in one pass and in two."""
    cap = capture_file("eclink_modbus_late_accept.pcap")
    for two in (False, True):
        r = tshark.fields(cap, ["frame.number", "eclink.image", "eclink_modbus.accepted_in"],
                          display_filter="eclink_modbus", two_pass=two)
        assert r == [["7", "input", "7"], ["8", "output", "7"], ["9", "", "7"]]


def test_detection_always(tshark, capture_file):
    cap = capture_file("eclink_modbus_late_accept.pcap")
    r = tshark.fields(cap, ["frame.number", "eclink.image", "eclink.pco"], display_filter="eclink_modbus",
                      prefs={"eclink_modbus.detection": "always"})
    assert r[:2] == [["4", "output", "1"], ["5", "", ""]]
    assert len(r) == 6


def test_detection_off(tshark, capture_file):
    cap = capture_file("eclink_modbus_basic.pcap")
    assert tshark.field(cap, "frame.number", display_filter="eclink || eclink_modbus",
                        prefs={"eclink_modbus.detection": "off"}) == []
    # Modbus itself is still decoded
    assert len(tshark.field(cap, "modbus.func_code", display_filter="modbus",
                            prefs={"eclink_modbus.detection": "off"})) == 48


def test_plain_devices_not_decoded(tshark, capture_file):
    cap = capture_file("modbus_plain_devices.pcap")
    assert tshark.field(cap, "frame.number", display_filter="eclink || eclink_modbus") == []
    assert len(tshark.field(cap, "frame.number", display_filter="modbus")) == 2 * (6 * 5 + 6 * 3 + 4)


def test_public_modbus_not_decoded(tshark, public_capture):
    cap = public_capture("modbus_example.pcap")
    assert tshark.field(cap, "frame.number", display_filter="eclink || eclink_modbus") == []
    assert tshark.field(cap, "frame.number", display_filter="eclink || eclink_modbus", two_pass=True) == []


def _plain_tshark_verbose(cap, conf_dir, tmp):
    """-V of the system tshark with none of our plugins."""
    env = dict(os.environ, TZ="UTC", LC_ALL="C.UTF-8", WIRESHARK_CONFIG_DIR=str(conf_dir), HOME=str(tmp))
    env.pop("WIRESHARK_PLUGIN_DIR", None)
    proc = subprocess.run(["tshark", "-n", "-r", str(cap), "-V"], env=env, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def _normalize(text):
    # the one difference a wrapping dissector cannot avoid: its name in the layer list
    return re.sub(r":eclink_modbus(?=[:\]])", "", text)


@pytest.mark.parametrize("which", ["public", "plain"])
def test_modbus_decoding_unchanged(tshark, public_capture, conf_dir, work_dir, which):
    cap = public_capture("modbus_example.pcap") if which == "public" else CAPTURES / "modbus_plain_devices.pcap"
    ours = tshark.verbose(cap)
    plain = _plain_tshark_verbose(cap, conf_dir, work_dir)
    assert "Modbus" in plain
    assert "eclink" not in _normalize(ours)
    assert _normalize(ours) == plain


def test_eclink_capture_keeps_modbus_tree(tshark, capture_file, conf_dir, work_dir):
    """On an EC-Link capture the Modbus trees are those of plain Wireshark; ours are added after them."""
    cap = capture_file("eclink_modbus_segments.pcap")
    ours = tshark.verbose(cap)
    plain = _plain_tshark_verbose(cap, conf_dir, work_dir)
    kept = []
    skip = False
    for line in _normalize(ours).splitlines():
        if line.startswith("EC-Link over Modbus/TCP"):
            skip = True
            continue
        if skip and line.startswith(" "):
            continue
        skip = False
        kept.append(line)
    assert "\n".join(kept) + "\n" == plain


def test_no_lua_errors_anywhere(tshark):
    """Every committed capture, verbose, one and two passes: no Lua error (the fixture checks)."""
    caps = sorted(Path(CAPTURES).glob("eclink_modbus_*.pcap")) + sorted(Path(CAPTURES).glob("modbus_plain_*.pcap"))
    assert len(caps) >= 9
    for cap in caps:
        tshark.verbose(cap)
        tshark.verbose(cap, two_pass=True, prefs={"eclink_modbus.assembled": "TRUE"})
        tshark.verbose(cap, prefs={"eclink_modbus.detection": "always"})
