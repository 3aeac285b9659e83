"""Broken machine descriptions: each kind of mistake is reported once, with the
file, the line, what is wrong and how to fix it (stderr and an expert item in
the first frame that uses the area); the rest of the description still loads
and decodes. Never a Lua error."""
import pytest

from conftest import CAPTURES
from io_testlib import io_tshark, problems, write

CAP = CAPTURES / "crane_eglink.pcap"

BROKEN = "\n".join([
    "area,byte,bit,type,name,label,unit,scale,offset,values,fault,severity,device",  # 1
    "cmd.from_ru,6,,u8,op,Operator,,,,,,,",                                           # 2 good
    "cmd.from_ru,6,0,bool,op_bit,,,,,,,,",                                            # 3 overlap
    "cmd.from_ru,15,,u16le,tail,,,,,,,,",                                             # 4 beyond
    "cmd.from_ru,8,,u16,speed,,,,,,,,",                                               # 5 type
    "cmd.to_ru,0,,u8,op,,,,,,,,",                                                     # 6 duplicate
    "periodic.to_ru,abc,,u8,y,,,,,,,,",                                               # 7 number
    'periodic.to_ru,0,,u16le,load,Load,t,"0,01",,,,,',                                # 8 decimal comma
    "hoist.up,0,,u8,z,,,,,,,,",                                                       # 9 area
    "# a comment line is skipped",                                                    # 10
    "periodic.to_ru,8,,u32le,cycle,Cycle,,,,,,,",                                     # 11 good
    "cmd.to_ru,2,,ascii:12,text,,,,,,,,",                                             # 12 good
    "periodic.to_ru,6,2-9,u8,flags,,,,,,,,",                                          # 13 bit range
    "periodic.to_ru,12,,floatle,wind,,,,,,2,fatal,",                                  # 14 severity
    "periodic.to_ru,16,,u8,Bad-Name,,,,,,,,",                                         # 15 name
    "cmd.to_ru,14,,u8,code,,,,,0=None;x,,,",                                           # 16 values
    "cmd.to_ru,15,,u8,dev,,,,,,,,unit=3",                                             # 17 device
]) + "\n"

MESSAGES = [
    "broken.csv line 3: 'op_bit' overlaps 'op' (line 2) in cmd.from_ru; fix: check byte, bit and type of "
    "both rows; two fields may not share a bit of the same area and device",
    "broken.csv line 4: bytes 15-16 are beyond the cmd.from_ru area (16 bytes); fix: use a byte offset "
    "from 0 to 14 for a 2-byte field",
    "broken.csv line 5: unknown type 'u16'; fix: say the byte order: u16le or u16be",
    "broken.csv line 6: duplicate name 'op' (first on line 2); fix: give every field its own name, or "
    "repeat the same field in another area with the same bit, type, label, unit, scale, offset and values",
    "broken.csv line 7: bad number 'abc' in column byte; fix: write the byte offset in the area as a "
    "whole number such as 4 or 0x04",
    "broken.csv line 8: bad number '0,01' in column scale; fix: write the decimal point as a point: 0.01, "
    "or separate the columns with ';' (a decimal comma is read in a ';' file)",
    "broken.csv line 9: unknown area 'hoist.up'; fix: write one of mcmb2.up, mcmb2.down, cmd.from_ru, "
    "cmd.to_ru, periodic.to_ru",
    "broken.csv line 13: bit '2-9' is outside the u8 (bits 0-7); fix: use a bit in range, or a wider type",
    "broken.csv line 14: unknown severity 'fatal'; fix: write warn or error (empty means warn)",
    "broken.csv line 15: bad name 'Bad-Name'; fix: use lower-case letters, digits and _ only, starting "
    "with a letter (it becomes vrshark.io.<name>)",
    "broken.csv line 16: bad value name 'x' in column values; fix: write value=name pairs separated by "
    "';', such as 0=Off;1=On",
    "broken.csv line 17: bad device key 'unit=3'; fix: write terminal=N, slot=N, frame_id=0xNNNN, origin=0xNNNN "
    "or server=<IP address>, or leave it empty for any device",
    "noheader.csv line 1: the header row has no column area, byte, type, name; fix: put the column names "
    "in the first row: area,byte,bit,type,name,label,unit,scale,offset,values,fault,severity,device",
]


@pytest.fixture
def broken(conf_dir, work_dir):
    write(work_dir, "broken.csv", BROKEN)
    write(work_dir, "noheader.csv", "where,what\ncmd.to_ru,u8\n")
    return io_tshark(conf_dir, work_dir)


@pytest.mark.parametrize("two_pass", [False, True])
def test_each_problem_reported_once_on_stderr(broken, two_pass):
    proc = broken.run(["-n", "-r", str(CAP)] + (["-2"] if two_pass else []))
    assert problems(proc) == MESSAGES


@pytest.mark.parametrize("two_pass", [False, True])
def test_problems_shown_in_the_first_frame_of_their_area(broken, two_pass):
    experts = broken.experts(CAP, two_pass=two_pass)
    shown = {n: [m for m in msgs if ".csv line " in m] for n, msgs in experts.items()}
    shown = {n: m for n, m in shown.items() if m}
    # periodic.to_ru is first used in frame 1 (with the problems that name no
    # area: line 9 and noheader.csv), cmd.from_ru in frame 2, cmd.to_ru in frame 11.
    assert shown == {
        1: [MESSAGES[6], MESSAGES[12], MESSAGES[4], MESSAGES[5], MESSAGES[7], MESSAGES[8], MESSAGES[9]],
        2: MESSAGES[0:3],
        11: [MESSAGES[3], MESSAGES[10], MESSAGES[11]],
    }
    assert broken.field(CAP, "frame.number", display_filter="vrshark_io.bad_description") == ["1", "2", "11"]


@pytest.mark.parametrize("two_pass", [False, True])
def test_the_rest_still_decodes(broken, two_pass):
    broken.expect(CAP, 2, {"vrshark.io.op": 7}, two_pass=two_pass)
    broken.expect(CAP, 10, {"vrshark.io.cycle": 4}, two_pass=two_pass)
    broken.expect(CAP, 11, {"vrshark.io.text": "LOAD 52.3 T "}, two_pass=two_pass)
    fields = broken.run(["-G", "fields"], allow_errors=True).stdout
    registered = sorted(line.split("\t")[2] for line in fields.splitlines() if "\tvrshark.io." in line)
    # every row with a problem was left out
    assert registered == ["vrshark.io.cycle", "vrshark.io.op", "vrshark.io.text"]


def test_duplicate_across_files_and_empty_file(conf_dir, work_dir):
    write(work_dir, "a.csv", "area,byte,type,name\ncmd.from_ru,6,u8,op\n")
    write(work_dir, "b.csv", "area;byte;type;name\ncmd.to_ru;0;u16le;op\ncmd.to_ru;2;u8;code\n")
    write(work_dir, "d.csv", "area,byte,type,name\nperiodic.to_ru,8,u8,op\n")
    write(work_dir, "c.csv", "")
    t = io_tshark(conf_dir, work_dir)
    proc = t.run(["-n", "-r", str(CAP)])
    assert problems(proc) == [
        "b.csv line 2: duplicate name 'op' (first in a.csv line 2); fix: give every field "
        "of all description files its own name, or repeat the same field in another area with the same "
        "bit, type, label, unit, scale, offset and values",
        "c.csv line 1: the file has no header row; fix: put the column names in the first row: "
        "area,byte,bit,type,name,label,unit,scale,offset,values,fault,severity,device",
    ]
    # b.csv is separated by ";" (as spreadsheets of many locales export it) and still loads.
    t.expect(CAP, 16, {"vrshark.io.code": 0x57, "vrshark.io.op": None})
    t.expect(CAP, 2, {"vrshark.io.op": 7})
    # the same field (same type, label...) in another area: one field, both places
    t.expect(CAP, 1, {"vrshark.io.op": 1})
