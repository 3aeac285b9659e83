-- vrshark.pnio_layout: where the MC-MB2-PN and EC-Link data sit in a PROFINET
-- IO cyclic frame.
--
-- A "plan" describes one cyclic frame (one FrameID, one direction):
--   system   "duplex" | "polled" | "eclink"
--   dir      "up" (input CR, device -> controller) | "down" (output CR)
--   source   where the layout comes from (text, shown in the tree)
--   fid      FrameID; sender: Ethernet source (an Address, compared with ==), or nil (any)
--   dev      key of the device (shared by both directions; analysis state)
--   header   { off, len, slot, subslot }   MC-MB2 header submodule
--   modules  { obj, ... }                   MC-MB2 data modules, slot order
--   image    obj                            EC-Link image submodule
--   dap      { obj, ... }                   slot 0 submodules (IOPS only)
--   iocs     { { off, slot, subslot }, ... } consumer status of the other
--                                            direction's submodules
--   need     C-SDU bytes the plan needs
--   cfg      polled: { n = slots, y = Y, z = Z } as configured
-- Every obj's IOPS is the byte after its data (off + len).
--
-- Three sources build plans: the Connect request/response (IOCR and expected
-- submodule blocks, parsed here from the bytes Wireshark's pn_io dissector
-- located), the user's layout table (preference), and a polled uplink header
-- (self-describing). The last two assume the usual frame layout: submodules in
-- slot order, each with data in this direction puts data + IOPS, each with
-- data in the other direction puts its IOCS.
--
-- No side effects at load time: the module only returns a table.
local M = {}

M.DATA_MODULES = { 20, 10, 8, 4, 2 }
M.ASCII_MODULES = { 40, 20, 10, 8, 4, 2 }
local DATA_SET = { [20] = true, [10] = true, [8] = true, [4] = true, [2] = true }
local DOWN_SET = { [40] = true, [20] = true, [10] = true, [8] = true, [4] = true, [2] = true }

-- Module sizes for n bytes, largest first; nil if n cannot be made of them.
function M.split(n, set)
    set = set or M.DATA_MODULES
    local out = {}
    for _, m in ipairs(set) do
        while n >= m do
            out[#out + 1] = m
            n = n - m
        end
    end
    if n ~= 0 then return nil end
    return out
end

local function sum(list, key)
    local s = 0
    for _, v in ipairs(list) do s = s + (key and v[key] or v) end
    return s
end

-- ---------------------------------------------------------------------------
-- Connect request / response blocks (big-endian, block header 6 bytes)
-- ---------------------------------------------------------------------------
local function mac_hex(tvb, off)
    return tostring(tvb:range(off, 6):bytes():tohex()):lower()
end
M.mac_hex = mac_hex

local function guid_hex(tvb, off)
    return tostring(tvb:range(off, 16):bytes():tohex())
end

-- Parses the block at tvb offset off into the AR record `ar` (created by the
-- caller as {}). Returns the block type handled, or nil.
function M.parse_block(ar, tvb, off)
    local tlen = tvb:len()
    if off + 6 > tlen then return nil end
    local btype = tvb:range(off, 2):uint()
    local blen = tvb:range(off + 2, 2):uint()
    local stop = off + 4 + blen
    if stop > tlen then return nil end
    local function u16(o) if o + 2 > stop then error("short") end return tvb:range(o, 2):uint() end
    local function u8(o) if o + 1 > stop then error("short") end return tvb:range(o, 1):uint() end
    local ok = pcall(function()
        if btype == 0x0101 and blen >= 54 then
            ar.uuid = guid_hex(tvb, off + 8)
            ar.ctl_mac = mac_hex(tvb, off + 26)
        elseif btype == 0x8101 and blen >= 30 then
            ar.uuid = ar.uuid or guid_hex(tvb, off + 8)
            ar.dev_mac = mac_hex(tvb, off + 26)
        elseif btype == 0x0102 then
            local cr = { type = u16(off + 6), ref = u16(off + 8), len = u16(off + 16), fid = u16(off + 18),
                         objs = {}, iocs = {} }
            local napi = u16(off + 44)
            local o = off + 46
            -- A count, then (slot, subslot, frame offset) entries; kept for API 0 only.
            local function entries(o2, api, list)
                local n = u16(o2)
                o2 = o2 + 2
                for _ = 1, n do
                    if api == 0 then
                        list[#list + 1] = { slot = u16(o2), subslot = u16(o2 + 2), off = u16(o2 + 4) }
                    end
                    o2 = o2 + 6
                end
                return o2
            end
            for _ = 1, napi do
                local api = tvb:range(o, 4):uint()
                o = entries(o + 4, api, cr.objs)     -- IO data objects
                o = entries(o, api, cr.iocs)         -- IOCS
            end
            ar.iocrs = ar.iocrs or {}
            ar.iocrs[cr.ref] = cr
        elseif btype == 0x8102 and blen >= 8 then
            ar.res_fids = ar.res_fids or {}
            ar.res_fids[u16(off + 8)] = u16(off + 10)
        elseif btype == 0x0104 then
            ar.subs = ar.subs or {}
            local napi = u16(off + 6)
            local o = off + 8
            for _ = 1, napi do
                local api = tvb:range(o, 4):uint()
                local slot = u16(o + 4)
                local nsub = u16(o + 12)
                o = o + 14
                for _ = 1, nsub do
                    local sub = { slot = slot, subslot = u16(o), inlen = 0, outlen = 0 }
                    local typ = bit.band(u16(o + 6), 3)
                    o = o + 8
                    for _ = 1, (typ == 3) and 2 or 1 do
                        local dd, dlen = u16(o), u16(o + 2)
                        u8(o + 5)
                        if dd == 1 then sub.inlen = dlen elseif dd == 2 then sub.outlen = dlen end
                        o = o + 6
                    end
                    if api == 0 then ar.subs[#ar.subs + 1] = sub end
                end
            end
        else
            btype = nil
        end
    end)
    if not ok then return nil end
    return btype
end

-- ---------------------------------------------------------------------------
-- Which system a set of expected submodules is
-- ---------------------------------------------------------------------------
local function by_slot(a, b)
    if a.slot ~= b.slot then return a.slot < b.slot end
    return a.subslot < b.subslot
end

local function non_increasing(list, last)
    for i = 2, last or #list do
        if list[i] > list[i - 1] then return false end
    end
    return true
end

-- Splits `sizes` into n equal groups; nil unless every group is the same.
local function groups_of(sizes, n)
    if n < 1 or #sizes % n ~= 0 then return nil end
    local per = #sizes / n
    for i = per + 1, #sizes do
        if sizes[i] ~= sizes[i - per] then return nil end
    end
    return per
end

-- Downlink modules of one terminal: data modules then ASCII modules, each
-- run largest first.
local function down_group_ok(list, first, last)
    local runs, prev = 1, nil
    for i = first, last do
        if prev and list[i] > prev then runs = runs + 1 end
        prev = list[i]
    end
    return runs <= 2
end

-- subs: { {slot, subslot, inlen, outlen}, ... } of API 0. Returns
-- { system, up = {hdr, data...}, down = {...}, cfg } or nil.
function M.classify(subs)
    local ins, outs = {}, {}
    local sorted = {}
    for _, s in ipairs(subs) do sorted[#sorted + 1] = s end
    table.sort(sorted, by_slot)
    for _, s in ipairs(sorted) do
        if s.slot ~= 0 then
            if s.subslot ~= 1 then return nil end
            if s.inlen > 0 and s.outlen > 0 then return nil end
            if s.inlen > 0 then ins[#ins + 1] = s
            elseif s.outlen > 0 then outs[#outs + 1] = s
            else return nil end
        end
    end
    -- EC-Link: slot 1 "Inputs" 64 bytes, slot 2 "Command Outputs" 20 or
    -- "Standard Outputs" 224 (or no output module: "Input Only").
    if #ins == 1 and ins[1].slot == 1 and ins[1].inlen == 64 then
        if #outs == 0 then return { system = "eclink", input = ins[1] } end
        if #outs == 1 and outs[1].slot == 2 and (outs[1].outlen == 20 or outs[1].outlen == 224) then
            return { system = "eclink", input = ins[1], output = outs[1] }
        end
        return nil
    end
    -- MC-MB2: uplink header, uplink data, downlink header, downlink data.
    if #ins < 2 or #outs < 1 then return nil end
    if ins[#ins].slot > outs[1].slot then return nil end
    local system
    if ins[1].inlen == 2 then system = "duplex" elseif ins[1].inlen == 8 then system = "polled" else return nil end
    if outs[1].outlen ~= 2 then return nil end
    local up, down = {}, {}
    for i = 2, #ins do
        if not DATA_SET[ins[i].inlen] then return nil end
        up[#up + 1] = ins[i].inlen
    end
    for i = 2, #outs do
        if not DOWN_SET[outs[i].outlen] then return nil end
        down[#down + 1] = outs[i].outlen
    end
    local res = { system = system, up_hdr = ins[1], down_hdr = outs[1], up = {}, down = {} }
    for i = 2, #ins do res.up[#res.up + 1] = ins[i] end
    for i = 2, #outs do res.down[#res.down + 1] = outs[i] end
    if system == "duplex" then
        if not non_increasing(up) or sum(up) > 254 then return nil end
        if #down > 0 and not down_group_ok(down, 1, #down) then return nil end
        res.cfg = { n = 1, y = sum(up), z = sum(down) }
        return res
    end
    -- Polled: n terminal slots with identical module groups in both directions.
    for n = 4, 1, -1 do
        local pu = groups_of(up, n)
        local pd = (#down == 0) and 0 or groups_of(down, n)
        if pu and pd then
            local good = non_increasing(up, pu)
            if good and (pd == 0 or down_group_ok(down, 1, pd)) then
                res.cfg = { n = n, y = sum(up) / n, z = sum(down) / n }
                return res
            end
        end
    end
    return nil
end

-- ---------------------------------------------------------------------------
-- Plans
-- ---------------------------------------------------------------------------
local function need_of(plan)
    local need = 0
    local function obj(o) if o and o.off + o.len + 1 > need then need = o.off + o.len + 1 end end
    obj(plan.header)
    obj(plan.image)
    for _, o in ipairs(plan.modules or {}) do obj(o) end
    for _, o in ipairs(plan.dap or {}) do obj(o) end
    for _, c in ipairs(plan.iocs or {}) do if c.off + 1 > need then need = c.off + 1 end end
    plan.need = need
    return plan
end

-- Plans for both directions of a classified Connect. ar: the parsed AR.
-- Returns up_plan, down_plan (either may be nil).
function M.plans_from_ar(ar, cls, source)
    local sizes = {}
    for _, s in ipairs(ar.subs) do
        sizes[s.slot * 65536 + s.subslot] = s
    end
    local plans = {}
    for ref, cr in pairs(ar.iocrs or {}) do
        local dir = (cr.type == 1) and "up" or ((cr.type == 2) and "down" or nil)
        if dir then
            local fid = (ar.res_fids and ar.res_fids[ref]) or cr.fid
            local plan = { system = cls.system, dir = dir, source = source, fid = fid, modules = {}, dap = {},
                           iocs = {}, cfg = cls.cfg, dev = ar.uuid }
            if dir == "up" then plan.sender = ar.dev_mac else plan.sender = ar.ctl_mac end
            local objs = {}
            for _, o in ipairs(cr.objs) do
                local s = sizes[o.slot * 65536 + o.subslot]
                local len = s and ((dir == "up") and s.inlen or s.outlen) or 0
                objs[#objs + 1] = { off = o.off, len = len, slot = o.slot, subslot = o.subslot }
            end
            table.sort(objs, by_slot)
            local hdr = (dir == "up") and cls.up_hdr or cls.down_hdr
            local image = (dir == "up") and cls.input or cls.output
            for _, o in ipairs(objs) do
                if o.slot == 0 then
                    plan.dap[#plan.dap + 1] = o
                elseif cls.system == "eclink" then
                    if image and o.slot == image.slot then plan.image = o end
                elseif hdr and o.slot == hdr.slot then
                    plan.header = o
                else
                    plan.modules[#plan.modules + 1] = o
                end
            end
            for _, c in ipairs(cr.iocs) do
                plan.iocs[#plan.iocs + 1] = { off = c.off, slot = c.slot, subslot = c.subslot }
            end
            table.sort(plan.iocs, by_slot)
            if (cls.system == "eclink" and plan.image) or (cls.system ~= "eclink" and plan.header) then
                plans[dir] = need_of(plan)
            end
        end
    end
    return plans.up, plans.down
end

-- The usual layout of a device whose submodules are, in slot order: `dap`
-- DAP submodules, then `ins` (input sizes), then `outs` (output sizes).
-- Returns the objects and IOCS of both frames:
--   { up = { dap, objs, iocs }, down = { dap, objs, iocs } }
function M.canonical(dap, ins, outs)
    local subs = {}
    for i = 1, dap do
        subs[#subs + 1] = { slot = 0, subslot = (i == 1) and 1 or (0x8000 + i - 2), inlen = 0, outlen = 0 }
    end
    local slot = 0
    for _, n in ipairs(ins) do
        slot = slot + 1
        subs[#subs + 1] = { slot = slot, subslot = 1, inlen = n, outlen = 0 }
    end
    for _, n in ipairs(outs) do
        slot = slot + 1
        subs[#subs + 1] = { slot = slot, subslot = 1, inlen = 0, outlen = n }
    end
    local res = {}
    for _, dir in ipairs({ "up", "down" }) do
        local r = { dap = {}, objs = {}, iocs = {} }
        local off = 0
        for _, s in ipairs(subs) do
            local mine = (dir == "up") and (s.outlen == 0) or (s.outlen > 0)
            if mine then
                local len = (dir == "up") and s.inlen or s.outlen
                local o = { off = off, len = len, slot = s.slot, subslot = s.subslot }
                if s.slot == 0 then r.dap[#r.dap + 1] = o else r.objs[#r.objs + 1] = o end
                off = off + len + 1
            else
                r.iocs[#r.iocs + 1] = { off = off, slot = s.slot, subslot = s.subslot }
                off = off + 1
            end
        end
        res[dir] = r
    end
    return res
end

-- Plans for an MC-MB2 device given by its terminal sizes (usual layout).
-- up_mods / down_mods: module sizes of ONE terminal; n: terminal slots.
function M.mcmb2_plans(system, n, up_mods, down_mods, dap, source, dev)
    local ins = { (system == "polled") and 8 or 2 }
    local outs = { 2 }
    for _ = 1, n do
        for _, m in ipairs(up_mods) do ins[#ins + 1] = m end
        for _, m in ipairs(down_mods) do outs[#outs + 1] = m end
    end
    local c = M.canonical(dap, ins, outs)
    local cfg = { n = n, y = sum(up_mods), z = sum(down_mods) }
    local plans = {}
    for _, dir in ipairs({ "up", "down" }) do
        local r = c[dir]
        local plan = { system = system, dir = dir, source = source, dev = dev, dap = r.dap, iocs = r.iocs,
                       cfg = cfg, modules = {} }
        plan.header = r.objs[1]
        for i = 2, #r.objs do plan.modules[#plan.modules + 1] = r.objs[i] end
        plans[dir] = need_of(plan)
    end
    return plans.up, plans.down
end

function M.eclink_plans(outlen, dap, source, dev)
    local c = M.canonical(dap, { 64 }, (outlen and outlen > 0) and { outlen } or {})
    local up = need_of({ system = "eclink", dir = "up", source = source, dev = dev, dap = c.up.dap,
                         iocs = c.up.iocs, image = c.up.objs[1], modules = {} })
    local down
    if outlen and outlen > 0 then
        down = need_of({ system = "eclink", dir = "down", source = source, dev = dev, dap = c.down.dap,
                         iocs = c.down.iocs, image = c.down.objs[1], modules = {} })
    end
    return up, down
end

-- ---------------------------------------------------------------------------
-- The layout table (preference)
--
--   entry   = IN [ "/" OUT ] "=" system [ ":" up [ "/" down ] ] [ "@" dap ]
--   IN/OUT  = FrameID of the input (uplink) and output (downlink) frame,
--             hexadecimal with 0x or decimal; "-" for none
--   system  = duplex | simplex | polled | eclink
--   up      = [ slots "x" ] sizes ; down = [ slots "x" ] sizes
--   sizes   = size { "," size } ; size = bytes | "a" bytes (ASCII modules)
-- Entries are separated by ";" (or newlines). Each size is split into
-- modules largest first (26 -> 20,4,2), so module lists and byte counts both
-- work. eclink: down is 20 or 224 (default 224), up is ignored.
-- Returns { entries }, { error strings }.
-- ---------------------------------------------------------------------------
local function parse_fid(s)
    s = s:match("^%s*(.-)%s*$")
    if s == "-" or s == "" then return false end
    local n = tonumber(s)
    if not n and s:match("^0[xX]%x+$") then n = tonumber(s:sub(3), 16) end
    if not n or n < 0 or n > 0xFFFF or n % 1 ~= 0 then return nil end
    return n
end

local function parse_sizes(s)
    local slots, mods = nil, {}
    s = s:gsub("%s", "")
    local cnt, rest = s:match("^(%d+)[xX](.*)$")
    if cnt then slots, s = tonumber(cnt), rest end
    if s == "" then return slots, mods end
    for item in s:gmatch("[^,]+") do
        local ascii, num = item:match("^([aA]?)(%d+)$")
        if not num then return nil, "bad size '" .. item .. "'" end
        local m = M.split(tonumber(num), (ascii ~= "") and M.ASCII_MODULES or M.DATA_MODULES)
        if not m then return nil, "size " .. item .. " is not made of modules" end
        for _, v in ipairs(m) do mods[#mods + 1] = v end
    end
    return slots, mods
end

function M.parse_table(text)
    local entries, errors = {}, {}
    for raw in (text or ""):gmatch("[^;\n]+") do
        local e = raw:match("^%s*(.-)%s*$")
        if e ~= "" then
            local fids, system, rest = e:match("^([^=]+)=%s*(%a+)%s*(.*)$")
            local err
            local entry = {}
            if not fids then
                err = "expected IN[/OUT]=system"
            else
                local a, b = fids:match("^([^/]+)/?(.*)$")
                entry.in_fid, entry.out_fid = parse_fid(a or ""), parse_fid(b or "")
                if entry.in_fid == nil or entry.out_fid == nil then err = "bad FrameID" end
                system = system:lower()
                if system == "simplex" then system = "duplex" end
                entry.system = system
                if system ~= "duplex" and system ~= "polled" and system ~= "eclink" then
                    err = err or ("unknown system '" .. system .. "'")
                end
                local dap = rest:match("@%s*(%d+)%s*$")
                entry.dap = tonumber(dap or "4")
                rest = rest:gsub("@%s*%d+%s*$", "")
                local spec = rest:match("^:%s*(.*)$") or ""
                if rest ~= "" and not rest:match("^:") then err = err or "expected ':' after the system" end
                local up, down = spec:match("^([^/]*)/?(.*)$")
                local m1, m2
                entry.up_slots, m1 = parse_sizes(up or "")
                if entry.up_slots == nil and type(m1) == "string" then err = err or m1 end
                entry.down_slots, m2 = parse_sizes(down or "")
                if entry.down_slots == nil and type(m2) == "string" then err = err or m2 end
                entry.up = (type(m1) == "table") and m1 or {}
                entry.down = (type(m2) == "table") and m2 or {}
                entry.slots = entry.up_slots or entry.down_slots
                if system == "eclink" then
                    entry.outlen = sum(entry.down)
                    if entry.outlen == 0 then entry.outlen = (entry.out_fid and 224) or 0 end
                    if entry.outlen ~= 0 and entry.outlen ~= 20 and entry.outlen ~= 224 then
                        err = err or "EC-Link output is 20 or 224 bytes"
                    end
                elseif system == "polled" and #entry.up > 0 and not entry.slots then
                    entry.slots = 1
                end
            end
            if err then errors[#errors + 1] = "'" .. e .. "': " .. err else entries[#entries + 1] = entry end
        end
    end
    return entries, errors
end

-- ---------------------------------------------------------------------------
-- The self-describing polled uplink header
--
-- get(i) returns C-SDU byte i (0-based) or nil past the end. Looks for `dap`
-- IOPS bytes followed by a polled header (status 0x0A/0x0F with terminal
-- nibble 0, Y and Z made of modules, four slot status bytes with defined low
-- nibbles) and its IOPS, then each used slot's modules with their IOPS, then
-- only IOCS / padding. Returns { dap, y, z, used, up_mods, down_mods } or nil.
-- ---------------------------------------------------------------------------
local IOXS_OK = { [0x00] = true, [0x20] = true, [0x40] = true, [0x60] = true, [0x80] = true }
local SLOT_OK = { [0] = true, [1] = true, [2] = true, [7] = true, [0xF] = true }
M.IOXS_OK = IOXS_OK

function M.polled_header(get, size)
    for dap = 1, 8 do
        -- the DAP IOPS, the 8-byte header and its IOPS must fit
        if dap + 9 > size then return nil end
        local ok = true
        for i = 0, dap - 1 do
            if not IOXS_OK[get(i)] then ok = false break end
        end
        if not ok then return nil end
        local h = dap
        local st = get(h)
        if (st == 0x0F or st == 0x0A) and h + 9 <= size then
            local y, z = get(h + 2), get(h + 3)
            local up_mods = M.split(y)
            local down_mods = (z == 0) and {} or M.split(z)
            local used = 0
            local slots_ok = true
            for k = 0, 3 do
                local s = get(h + 4 + k)
                if not SLOT_OK[bit.band(s, 0x0F)] then slots_ok = false break end
                if bit.band(s, 0x0F) ~= 0x0F then used = used + 1 end
            end
            if y > 0 and up_mods and down_mods and slots_ok and used > 0 and IOXS_OK[get(h + 8)] then
                -- The modules and their IOPS.
                local off = h + 9
                for _ = 1, used do
                    for _, m in ipairs(up_mods) do
                        off = off + m
                        if off >= size or not IOXS_OK[get(off)] then ok = false break end
                        off = off + 1
                    end
                    if not ok then break end
                end
                -- Then IOCS of the downlink submodules (header + modules), then padding.
                if ok then
                    local ncs = 1 + used * #down_mods
                    for i = off, size - 1 do
                        local b = get(i)
                        if i < off + ncs then
                            if not IOXS_OK[b] then ok = false break end
                        elseif b ~= 0 then
                            ok = false
                            break
                        end
                    end
                end
                if ok then
                    return { dap = dap, y = y, z = z, used = used, up_mods = up_mods, down_mods = down_mods }
                end
            end
        end
    end
    return nil
end

return M
