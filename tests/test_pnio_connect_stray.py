"""A Connect whose IOCR names an IO data object that none of its expected
submodules describes (a corrupt or foreign request; found by tools/fuzz)
gives that direction no length to decode with; one whose IOCR leaves out
the header (EC-Link: the image) it expects gives it nothing to start from.
The direction is not learned, and said so: on the Connect, in the text of the learned layout;
on each of its cyclic frames, the mcmb2.candidate note naming the setting
that decodes it (mcmb2.layouts). The other direction decodes as usual;
one pass and two passes agree; never a Lua error."""
import pytest

from pnio_testlib import CaptureFile, Device, eclink_submodules, mac, mcmb2_submodules
from test_pnio_midsession import _slots, _spread, eclink_image_in

FIELDS = ["mcmb2.system", "mcmb2.direction", "mcmb2.candidate_setting", "_ws.expert.message"]


class StrayDevice(Device):
    """Its Connect names slot `stray` of the IOCR of `direction` with
    subslot 0x78 (the expected submodule is subslot 1), or leaves that
    slot's IO data object out (`drop`)."""
    stray = None
    drop = False

    def _iocr(self, direction, ref, fid):
        block = super()._iocr(direction, ref, fid)
        if self.stray and self.stray[0] == direction:
            objs = block.APIs[0].IODataObjects
            for obj in objs:
                if obj.SlotNumber == self.stray[1]:
                    obj.SubslotNumber = 0x78
            if self.drop:
                block.APIs[0].IODataObjects = [o for o in objs if o.SlotNumber != self.stray[1]]
        return block


def capture(work_dir, direction, slot, drop=False):
    d = StrayDevice(mcmb2_submodules("duplex", 4, 8, 4, 0, 1), mac(50), 0x8050, 0x8051)
    d.stray, d.drop = (direction, slot), drop
    cap = CaptureFile()
    for p in d.connect():
        cap.add(p)
    ins, outs = _slots(d, "in"), _slots(d, "out")
    for i in range(3):
        cap.add(d.cyclic("in", _spread(ins, "inlen", bytes([0x03, i + 1]) + bytes(8))), 0.004)
        cap.add(d.cyclic("out", _spread(outs, "outlen", bytes([1, i + 1, 1, 2, 3, 4]))), 0.001)
    return cap.write(work_dir / ("stray-%s%s.pcap" % (direction, "-drop" if drop else "")))


# (direction, the slot made stray (a module of it) or left out (its header), ...)
@pytest.mark.parametrize("direction,slot,fid,name,drop", [
    ("out", 4, 0x8051, "downlink", False), ("in", 1, 0x8050, "uplink", False),
    ("out", 3, 0x8051, "downlink", True), ("in", 1, 0x8050, "uplink", True)])
def test_a_stray_io_data_object_leaves_its_direction_unlearned_and_says_so(tshark, work_dir, direction, slot,
                                                                              fid, name, drop):
    path = capture(work_dir, direction, slot, drop)
    if drop:
        why = "%s IOCR places no IO data object of the header (slot %d/0x1)" % (name, slot)
    else:
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


def test_an_eclink_iocr_without_its_output_image_leaves_the_downlink_unlearned_and_says_so(tshark, work_dir):
    d = StrayDevice(eclink_submodules(4, 20), mac(51), 0x8060, 0x8061)
    d.stray, d.drop = ("out", 2), True
    cap = CaptureFile()
    for p in d.connect():
        cap.add(p)
    for i in range(3):
        cap.add(d.cyclic("in", {1: eclink_image_in(i)}), 0.004)
        cap.add(d.cyclic("out", {}), 0.001)
    path = cap.write(work_dir / "stray-eclink.pcap")
    why = "downlink IOCR places no IO data object of the output image (slot 2/0x1)"
    for two_pass in (False, True):
        got = tshark.frames(path, ["eclink.image", "eclink.pci", "mcmb2.candidate_setting", "_ws.expert.message"],
                            two_pass=two_pass)
        assert got[1]["_ws.expert.message"] == (
            "Cyclic data layout learned: eclink device: uplink FrameID 0x8060, downlink FrameID 0x8061 not learned "
            "(%s)" % why)
        for n in (3, 5, 7):
            assert (got[n]["eclink.image"], got[n]["eclink.pci"]) == ("input", str((n - 3) // 2)), n
        for n in (4, 6, 8):
            assert got[n] == {"eclink.image": "", "eclink.pci": "", "mcmb2.candidate_setting": "mcmb2.layouts",
                              "_ws.expert.message": "Not decoded: the Connect of an EC-Link BU does not describe "
                                                    "this downlink (%s); to decode it: its layout in mcmb2.layouts"
                                                    % why}, n
