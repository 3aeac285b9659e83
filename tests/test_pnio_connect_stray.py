"""A Connect whose IOCR names an IO data object that none of its expected
submodules describes (a corrupt or foreign request; found by tools/fuzz)
gives that direction no length to decode with. The direction is not
learned, and said so: on the Connect, in the text of the learned layout;
on each of its cyclic frames, the mcmb2.candidate note naming the setting
that decodes it (mcmb2.layouts). The other direction decodes as usual;
one pass and two passes agree; never a Lua error."""
import pytest

from pnio_testlib import CaptureFile, Device, mac, mcmb2_submodules
from test_pnio_midsession import _slots, _spread

FIELDS = ["mcmb2.system", "mcmb2.direction", "mcmb2.candidate_setting", "_ws.expert.message"]


class StrayDevice(Device):
    """Its Connect names slot `stray` of the IOCR of `direction` with
    subslot 0x78 (the expected submodule is subslot 1)."""
    stray = None

    def _iocr(self, direction, ref, fid):
        block = super()._iocr(direction, ref, fid)
        if self.stray and self.stray[0] == direction:
            for obj in block.APIs[0].IODataObjects:
                if obj.SlotNumber == self.stray[1]:
                    obj.SubslotNumber = 0x78
        return block


def capture(work_dir, direction, slot):
    d = StrayDevice(mcmb2_submodules("duplex", 4, 8, 4, 0, 1), mac(50), 0x8050, 0x8051)
    d.stray = (direction, slot)
    cap = CaptureFile()
    for p in d.connect():
        cap.add(p)
    ins, outs = _slots(d, "in"), _slots(d, "out")
    for i in range(3):
        cap.add(d.cyclic("in", _spread(ins, "inlen", bytes([0x03, i + 1]) + bytes(8))), 0.004)
        cap.add(d.cyclic("out", _spread(outs, "outlen", bytes([1, i + 1, 1, 2, 3, 4]))), 0.001)
    return cap.write(work_dir / ("stray-%s.pcap" % direction))


# (direction of the stray object, its slot: the header of that direction)
@pytest.mark.parametrize("direction,slot,fid,name", [("out", 4, 0x8051, "downlink"), ("in", 1, 0x8050, "uplink")])
def test_a_stray_io_data_object_leaves_its_direction_unlearned_and_says_so(tshark, work_dir, direction, slot,
                                                                              fid, name):
    path = capture(work_dir, direction, slot)
    why = "%s IO data object of slot %d/0x78 has no expected %s submodule" % (
        name, slot, "output" if direction == "out" else "input")
    up = "0x8050" + (" not learned (%s)" % why if direction == "in" else "")
    down = "0x8051" + (" not learned (%s)" % why if direction == "out" else "")
    note = {"mcmb2.system": "", "mcmb2.direction": "", "mcmb2.candidate_setting": "mcmb2.layouts",
            "_ws.expert.message": "Not decoded: the Connect of an MC-MB2-PN duplex/simplex base does not describe "
                                  "this %s (%s); to decode it: its layout in mcmb2.layouts" % (name, why)}
    for two_pass in (False, True):
        got = tshark.frames(path, FIELDS, two_pass=two_pass)
        assert got[1]["_ws.expert.message"] == (
            "Cyclic data layout learned: duplex device: uplink FrameID %s, downlink FrameID %s" % (up, down))
        stray_frames = range(3, 9, 2) if direction == "in" else range(4, 9, 2)
        good_frames = range(4, 9, 2) if direction == "in" else range(3, 9, 2)
        for n in stray_frames:
            assert got[n] == note, n
        for n in good_frames:
            assert got[n]["mcmb2.system"] == "duplex", n
            assert got[n]["mcmb2.direction"] == ("downlink" if direction == "in" else "uplink"), n
    assert "Lua Error" not in tshark.verbose(path, two_pass=True)
