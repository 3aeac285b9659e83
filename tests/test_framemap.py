"""lua/vrshark/framemap.luam's packed maps, exercised inside tshark (a script
run with -X lua_script that requires the module from lua/ and writes what it
finds): every frame reads back what was set, before and after its chunk was
packed, after a value was set into a packed chunk again, and where a chunk
had to stay a table."""

SCRIPT = r"""
package.path = %(lua)r .. "/?.luam;" .. package.path
local fm = require("vrshark.framemap")
local out = assert(io.open(%(out)r, "w"))
local bad = 0
local function check(what, got, want)
    if got ~= want then
        bad = bad + 1
        if bad <= 20 then out:write(string.format("BAD %%s: got %%s, want %%s\n", what, tostring(got), tostring(want))) end
    end
end

-- records: two shared tables, one-off tables now and then, frames of none
local A, B = { name = "A" }, { name = "B" }
local refs, want = fm.packed_refs(), {}
for n = 1, 5000 do
    local v
    if n %% 97 == 0 then v = { name = "once" .. n }
    elseif n %% 5 == 0 then v = nil
    elseif n %% 2 == 0 then v = A else v = B end
    -- frames 3000..4999: a sparse stretch (few frames of ours)
    if n >= 3000 and n %% 50 ~= 0 then v = nil end
    want[n] = v
    fm.set(refs, n, v)
end
local packed = 0
for _ in pairs(refs.packed) do packed = packed + 1 end
out:write("refs packed chunks ", packed, "\n")
for n = 1, 5000 do check("refs " .. n, fm.get(refs, n), want[n]) end
-- a value set into a packed chunk (a later note on an earlier frame)
local note = { name = "note" }
fm.set(refs, 10, note)
want[10] = note
fm.set(refs, 11, nil)
want[11] = nil
for n = 1, 5000 do check("refs after " .. n, fm.get(refs, n), want[n]) end
out:write("refs chunk 0 a table again ", tostring(refs[0] ~= nil and refs.packed[0] == nil), "\n")
-- the map moves past another chunk: chunk 0 is packed anew
fm.set(refs, 5200, A)
want[5200] = A
out:write("refs chunk 0 packed anew ", tostring(refs[0] == nil and refs.packed[0] ~= nil), "\n")
for n = 1, 5200 do check("refs repacked " .. n, fm.get(refs, n), want[n]) end

-- ages in ms (false: none); chunk 1024 of ages not rounded to the ms, one
-- such age in chunk 2048
local ms, wantms = fm.packed_ms(), {}
for n = 1, 4000 do
    local v = (n %% 7 == 0) and false or math.floor(n * 1.25 + 0.5) / 1000
    if v and n >= 1024 and n < 2048 then v = v + 0.00001 end
    if n == 2500 then v = 0.0001 end
    wantms[n] = v
    fm.set(ms, n, v)
end
out:write("ms packed ", tostring(ms.packed[0] ~= nil), " ", tostring(ms.packed[1024] ~= nil), " ",
          tostring(ms.packed[2048] ~= nil), "\n")
for n = 1, 4000 do check("ms " .. n, fm.get(ms, n) or false, wantms[n]) end

-- times in whole microseconds (the Modbus decoder's response times and
-- ages): chunk 0 packs with one value beside it (not whole microseconds),
-- chunk 1024 keeps a value over 71 minutes beside it
local us, wantus = fm.packed_us(), {}
for n = 1, 2100 do
    local v = (n %% 3 == 0) and false or (n * 37 %% 100000) / 1e6
    if n == 5 then v = 0.0000005 end
    if n == 1500 then v = 5000 end
    wantus[n] = v
    fm.set(us, n, v)
end
out:write("us packed ", tostring(us.packed[0] ~= nil), " ", tostring(us.packed[1024] ~= nil), " rest ",
          tostring(us.rest[5]), " ", tostring(us.rest[1500]), "\n")
for n = 1, 2100 do check("us " .. n, fm.get(us, n) or false, wantus[n]) end
out:write("bad ", bad, "\n")
out:close()
"""


def test_packed_maps_read_back(lua_probe):
    lines = lua_probe(SCRIPT)
    # chunks 0 and 1024 dense, 2048 dense up to frame 2999; 3072 sparse stays a table; 4096 is the last
    # ages: chunk 1024 (no age rounded to the ms) stays a table; 2048 keeps its one such age beside
    # a set into a packed chunk makes it a table until the map moves past another chunk
    # times in us: values not whole us, or past 4294 s, stay beside the string
    assert lines == ["refs packed chunks 3", "refs chunk 0 a table again true", "refs chunk 0 packed anew true",
                     "ms packed true false true", "us packed true true rest 5e-07 5000", "bad 0"], "\n".join(lines)
