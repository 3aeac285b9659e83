"""Foreign PROFINET traffic: nothing of ours, Wireshark's own decoding unchanged."""
import os
import subprocess

import pytest

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


@pytest.mark.parametrize("name", PUBLIC)
def test_wireshark_decoding_unchanged(tshark, public_capture, name, work_dir):
    ours = tshark.verbose(public_capture(name))
    env = dict(os.environ, TZ="UTC", LC_ALL="C.UTF-8", WIRESHARK_CONFIG_DIR=str(work_dir), HOME=str(work_dir))
    plain = subprocess.run(["tshark", "-n", "-r", str(public_capture(name)), "-V"], env=env,
                           capture_output=True, text=True, errors="replace").stdout
    assert "PROFINET IO" in plain
    assert ours == plain


@pytest.mark.parametrize("name", PUBLIC)
def test_disabling_the_carrier_changes_nothing(tshark, public_capture, name):
    fields = ["frame.number", "pn_rt.frame_id", "pn_io.ioxs", "pn_io.frame_id", "_ws.col.Info",
              "frame.protocols"]
    assert tshark.fields(public_capture(name), fields) == \
        tshark.fields(public_capture(name), fields, extra=["--disable-protocol", "vrshark_pnio"])
