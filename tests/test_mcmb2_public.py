"""Foreign PROFINET traffic: nothing of ours, Wireshark's own decoding unchanged."""
import os
import re
import subprocess

import pytest

from conftest import assert_fields

PUBLIC = ["pnio_connect_and_cyclic.pcap", "pnio_connect_many.pcapng"]


@pytest.mark.parametrize("name", PUBLIC)
@pytest.mark.parametrize("two_pass", [False, True])
def test_no_field_of_ours(tshark, public_capture, name, two_pass):
    rows = tshark.fields(public_capture(name), ["frame.number"], two_pass=two_pass,
                         display_filter="mcmb2 || eclink || eclink_pnio || mcmb2.system || eclink.image")
    assert rows == []
    # and the capture does hold cyclic data and Connects
    n = tshark.fields(public_capture(name), ["frame.number"], display_filter="pn_io.block_type == 0x0101")
    assert n


def _normalize(text):
    # the one difference a wrapping dissector cannot avoid: its name in the layer list
    return re.sub(r":vrshark_pnio(?=[:\]])", "", text)


@pytest.mark.parametrize("name", PUBLIC)
def test_wireshark_decoding_unchanged(tshark, public_capture, name, work_dir):
    ours = tshark.verbose(public_capture(name))
    env = dict(os.environ, TZ="UTC", LC_ALL="C.UTF-8", WIRESHARK_CONFIG_DIR=str(work_dir), HOME=str(work_dir))
    env.pop("WIRESHARK_PLUGIN_DIR", None)
    plain = subprocess.run(["tshark", "-n", "-r", str(public_capture(name)), "-V"], env=env,
                           capture_output=True, text=True, errors="replace").stdout
    assert "PROFINET IO" in plain
    assert "vrshark_pnio" in ours  # the carrier did see the frames
    assert "mcmb2" not in _normalize(ours) and "eclink" not in _normalize(ours)
    assert _normalize(ours) == plain


@pytest.mark.parametrize("name", PUBLIC)
def test_only_the_layer_list_changes(tshark, public_capture, name):
    fields = ["pn_rt.frame_id", "pn_io.ioxs", "pn_io.frame_id", "pn_io.block_type", "_ws.col.Info",
              "frame.protocols"]
    ours = tshark.frames(public_capture(name), fields)
    plain = tshark.frames(public_capture(name), fields, extra=["--disable-protocol", "vrshark_pnio"])
    assert sorted(ours) == sorted(plain)
    for n, a in ours.items():
        b = plain[n]
        if "pn_rt" in a["frame.protocols"]:
            # Disabled, the carrier takes EtherType 0x8892 with it: PN-RT frames become data
            assert_fields(b, {"pn_rt.frame_id": None, "pn_io.ioxs": None}, "frame %d, disabled" % n)
            assert b["frame.protocols"].endswith(":data")
            assert a["frame.protocols"].startswith("eth:ethertype:") and ":vrshark_pnio:pn_rt" in a["frame.protocols"]
        else:
            # DCE/RPC (PNIO-CM) still reaches Wireshark's heuristic: unchanged but for the layer list
            assert dict(a, **{"frame.protocols": _normalize(a["frame.protocols"])}) == b, "frame %d" % n
