--[[ mcmb2_pnio.lua -- MC-MB2-PN (SP-14-023) and EC-Link (TS-0007) images in
PROFINET IO cyclic data (protocols "mcmb2" and "eclink_pnio").

Transport: PROFINET RT, EtherType 0x8892 (optionally 802.1Q tagged):

  FrameID (2) | C-SDU (40..1440) | CycleCounter (2) | DataStatus (1) | TransferStatus (1)

Wireshark's own pn_rt/pn_io dissectors decode the frame as always: the
carrier protocol "vrshark_pnio" takes EtherType 0x8892 (tagged frames reach it
through the same table), calls Wireshark's PN-RT dissector first and then
decodes the C-SDU of the FrameIDs it knows (an unknown FrameID costs a table
lookup). The Connect request/response (DCE/RPC over UDP, PNIO-CM) reaches the
carrier through UDP port 34964 and, for the response coming from the device's
own port, through the controller's port learned from the request; it hands the
datagram to the UDP heuristics (where Wireshark finds DCE/RPC) and reads the
blocks from the bytes. Other traffic never reaches the plugin.

Inside the C-SDU every submodule's data is followed by its IOPS byte; the
IOCS bytes of the other direction's submodules sit at offsets of their own.
They are shown and stripped: the data of one terminal is the concatenation of
its modules' data. Layouts come from, best first:
  1. the Connect request/response in the capture (pn_io: IOCR blocks give
     FrameIDs and frame offsets, ExpectedSubmodule blocks the lengths);
  2. the preference table (mcmb2.layouts, format in README and
     vrshark/pnio_layout.lua);
  3. a polled uplink header, which describes itself (Y, Z, slot status);
     the downlink from the controller to the same device is laid out with it.

MC-MB2-PN uplink (device -> controller), duplex/simplex:
  0 status (bits 0-3 status 0,1,2,7,0xA; bits 4-7 terminal) | 1 watchdog | 2.. data
MC-MB2-PN downlink, duplex/simplex:
  0 base unit number | 1 watchdog | 2.. data (none on simplex)
Polled uplink:
  0 status (0xA or 0xF, bits 4-7 zero) | 1 watchdog | 2 Y | 3 Z |
  4..7 slot status (bits 0-3 0,1,2,7,0xF; bits 4-7 terminal) | Y bytes per used slot
Polled downlink:
  0 reserved (0) | 1 watchdog | Z bytes per used slot
EC-Link: slot 1 input image (64), slot 2 output image (20 or 224), decoded by
vrshark/eclink_image.lua; the handshake counters are supervised by
vrshark/eclink_handshake.lua (the same rules and messages as over Modbus/TCP).

All analysis runs on the first pass in frame order and is stored per frame,
so tshark -2 and clicking around show the same as one pass.
]]

local dir = debug.getinfo(1, "S").source:match("^@(.*)[/\\]")
package.path = dir .. "/?.luam;" .. package.path
set_plugin_info(require("vrshark.version").info(
    "PROFINET carrier, Cavotec MC-MB2-PN cyclic frames and EC-Link images over PROFINET"))
local layout = require("vrshark.pnio_layout")
local handshake = require("vrshark.handshake")
local eclink_handshake = require("vrshark.eclink_handshake")
local image = require("vrshark.eclink_image")
local wrap = require("vrshark.wrap")
local fe = require("vrshark.frontends")
local iodata = require("vrshark.iodata") -- vrshark_io hook
image.proto()

------------------------------------------------------------------------
-- Protocols
------------------------------------------------------------------------
local mcmb2 = Proto("mcmb2", "MC-MB2-PN radio base unit (PROFINET IO)")
local eclp = Proto("eclink_pnio", "EC-Link over PROFINET IO")
-- The carrier: wraps PN-RT (EtherType 0x8892) and PNIO-CM (UDP), learns
-- layouts from the Connect and finds our cyclic frames. With the C front
-- ends (vrshark.frontends) the C plugin is the protocol "vrshark_pnio" and
-- wraps them; the decoder registered into its tables is then mcmb2's.
local C = fe.pn_frame_id ~= nil
local carrier = C and mcmb2 or Proto("vrshark_pnio", "vrshark PROFINET IO cyclic data")
local ethertype_table = DissectorTable.get("ethertype")
local udp_table = DissectorTable.get("udp.port")
local pn_rt = ethertype_table:get_dissector(0x8892)
local ETH_PNRT, UDP_PNIO_CM = 0x8892, 34964

------------------------------------------------------------------------
-- Value tables
------------------------------------------------------------------------
local STATUS = {
    [0x0] = "Terminal absent",
    [0x1] = "Terminal present",
    [0x2] = "Terminal blocked (waiting for start key)",
    [0x7] = "Active stop",
    [0xA] = "Fieldbus update failure (E010)",
    [0xF] = "Polled system normal mode",
}
local SLOT_STATUS = {
    [0x0] = "Terminal absent",
    [0x1] = "Terminal present",
    [0x2] = "Terminal blocked (waiting for start key)",
    [0x7] = "Active stop",
    [0xF] = "Slot not used",
}
local DUPLEX_OK = { [0x0] = true, [0x1] = true, [0x2] = true, [0x7] = true, [0xA] = true }
local POLLED_OK = { [0xA] = true, [0xF] = true }
local SLOT_OK = { [0x0] = true, [0x1] = true, [0x2] = true, [0x7] = true, [0xF] = true }
local SLOT_ANCHOR = { "slot1", "slot2", "slot3", "slot4" }
local IOXS = {
    [0x80] = "Good",
    [0x00] = "Bad (by subslot)",
    [0x20] = "Bad (by slot)",
    [0x40] = "Bad (by IO device)",
    [0x60] = "Bad (by IO controller)",
}

------------------------------------------------------------------------
-- Fields
------------------------------------------------------------------------
local pf = {
    system = ProtoField.string("mcmb2.system", "System"),
    direction = ProtoField.string("mcmb2.direction", "Direction"),
    layout = ProtoField.string("mcmb2.layout", "Layout from"),
    status = ProtoField.uint8("mcmb2.status", "MC-MB2-PN status", base.HEX, STATUS, 0x0F),
    terminal = ProtoField.uint8("mcmb2.terminal", "Terminal number", base.DEC, nil, 0xF0),
    uplink_watchdog = ProtoField.uint8("mcmb2.uplink_watchdog", "Uplink watchdog counter", base.DEC),
    uplink_data = ProtoField.bytes("mcmb2.uplink_data", "Uplink data from terminal"),
    uplink_size = ProtoField.uint8("mcmb2.uplink_size", "Uplink data area size (Y)", base.DEC),
    downlink_size = ProtoField.uint8("mcmb2.downlink_size", "Downlink data area size (Z)", base.DEC),
    slot = ProtoField.uint8("mcmb2.slot", "Data slot", base.DEC),
    slot_status = ProtoField.uint8("mcmb2.slot.status", "Terminal status", base.HEX, SLOT_STATUS, 0x0F),
    slot_terminal = ProtoField.uint8("mcmb2.slot.terminal", "Terminal number", base.DEC, nil, 0xF0),
    slot_uplink_data = ProtoField.bytes("mcmb2.slot.uplink_data", "Uplink data"),
    base_unit = ProtoField.uint8("mcmb2.base_unit", "Base unit number", base.DEC),
    reserved = ProtoField.uint8("mcmb2.reserved", "Reserved", base.HEX),
    downlink_watchdog = ProtoField.uint8("mcmb2.downlink_watchdog", "Downlink watchdog counter", base.DEC),
    downlink_data = ProtoField.bytes("mcmb2.downlink_data", "Downlink data to terminal"),
    slot_downlink_data = ProtoField.bytes("mcmb2.slot.downlink_data", "Downlink data"),
    iops = ProtoField.uint8("mcmb2.iops", "IOPS", base.HEX, IOXS),
    iocs = ProtoField.uint8("mcmb2.iocs", "IOCS", base.HEX, IOXS),
    watchdog_age = ProtoField.relative_time("mcmb2.watchdog_age", "Watchdog unchanged for"),
    frame_id = ProtoField.uint16("mcmb2.frame_id", "FrameID", base.HEX),
}
mcmb2.fields = pf

local ef = {
    status_undefined = ProtoExpert.new("mcmb2.status.undefined",
        "Undefined MC-MB2-PN status: bring the system to a safe state", expert.group.PROTOCOL,
        expert.severity.ERROR),
    slot_status_undefined = ProtoExpert.new("mcmb2.slot.status.undefined",
        "Undefined terminal status: bring the system to a safe state", expert.group.PROTOCOL,
        expert.severity.ERROR),
    terminal_not_zero = ProtoExpert.new("mcmb2.terminal.not_zero",
        "Terminal number bits of a polled status byte are not 0", expert.group.PROTOCOL, expert.severity.WARN),
    not_valid = ProtoExpert.new("mcmb2.no_valid_data",
        "No valid terminal data: the IO controller must keep the system in a safe state",
        expert.group.PROTOCOL, expert.severity.WARN),
    data_not_zero = ProtoExpert.new("mcmb2.data_not_zero",
        "Status is not 'present' but the uplink data is not all 0", expert.group.PROTOCOL, expert.severity.WARN),
    uplink_stalled = ProtoExpert.new("mcmb2.uplink_watchdog.stalled",
        "Uplink watchdog unchanged for over 1 s: bring the system to a safe state", expert.group.SEQUENCE,
        expert.severity.ERROR),
    downlink_stalled = ProtoExpert.new("mcmb2.downlink_watchdog.stalled",
        "Downlink watchdog unchanged for over 2000 ms: the base shows E010", expert.group.SEQUENCE,
        expert.severity.ERROR),
    terminal_changed = ProtoExpert.new("mcmb2.slot.terminal_changed",
        "Slot changed terminal (dynamic polling)", expert.group.SEQUENCE, expert.severity.NOTE),
    layout_mismatch = ProtoExpert.new("mcmb2.layout_mismatch",
        "Polled layout (Y/Z/slots) differs from the configured layout: bring the system to a safe state",
        expert.group.PROTOCOL, expert.severity.ERROR),
    iops_bad = ProtoExpert.new("mcmb2.iops.bad", "IOPS is not GOOD (0x80)", expert.group.PROTOCOL,
        expert.severity.WARN),
    iocs_bad = ProtoExpert.new("mcmb2.iocs.bad", "IOCS is not GOOD (0x80)", expert.group.PROTOCOL,
        expert.severity.WARN),
    reserved_not_zero = ProtoExpert.new("mcmb2.reserved.not_zero", "Reserved byte is not 0",
        expert.group.PROTOCOL, expert.severity.WARN),
    short = ProtoExpert.new("mcmb2.short", "C-SDU shorter than the layout", expert.group.MALFORMED,
        expert.severity.ERROR),
    learned = ProtoExpert.new("mcmb2.layout.learned", "Cyclic data layout learned from this Connect",
        expert.group.SEQUENCE, expert.severity.CHAT),
}
mcmb2.experts = { ef.status_undefined, ef.slot_status_undefined, ef.terminal_not_zero, ef.not_valid,
                  ef.data_not_zero, ef.uplink_stalled, ef.downlink_stalled, ef.terminal_changed,
                  ef.layout_mismatch, ef.iops_bad, ef.iocs_bad, ef.reserved_not_zero, ef.short, ef.learned }

local epf = {
    pci_age = ProtoField.relative_time("eclink_pnio.pci_age", "Time since PCI changed"),
    pco_age = ProtoField.relative_time("eclink_pnio.pco_age", "Time since PCO changed"),
    layout = ProtoField.string("eclink_pnio.layout", "Layout from"),
    iops = ProtoField.uint8("eclink_pnio.iops", "IOPS", base.HEX, IOXS),
    iocs = ProtoField.uint8("eclink_pnio.iocs", "IOCS", base.HEX, IOXS),
}
eclp.fields = epf
-- the handshake experts (same wording as over Modbus/TCP) come from vrshark.eclink_handshake
local eef, eclp_experts = eclink_handshake.experts("eclink_pnio")
eef.iops_bad = ProtoExpert.new("eclink_pnio.iops.bad", "IOPS is not GOOD (0x80)", expert.group.PROTOCOL,
    expert.severity.WARN)
eef.short = ProtoExpert.new("eclink_pnio.short", "C-SDU shorter than the layout", expert.group.MALFORMED,
    expert.severity.ERROR)
eef.learned = ProtoExpert.new("eclink_pnio.layout.learned", "Cyclic data layout learned from this Connect",
    expert.group.SEQUENCE, expert.severity.CHAT)
for _, k in ipairs({ "iops_bad", "short", "learned" }) do eclp_experts[#eclp_experts + 1] = eef[k] end
eclp.experts = eclp_experts

------------------------------------------------------------------------
-- Preferences
------------------------------------------------------------------------
mcmb2.prefs.layouts = Pref.string("Layout table", "",
    "FrameID layouts used when the capture has no Connect, separated by ';'. "
    .. "IN[/OUT]=SYSTEM[:UP[/DOWN]][@DAP], e.g. 0x8001/0x8002=duplex:26/10,a20 ; "
    .. "0x8003/0x8004=polled:4x24/4x10 ; 0x8005/0x8006=eclink:/224 (see README)")
mcmb2.prefs.connect = Pref.bool("Learn layouts from the Connect", true,
    "Recognise MC-MB2-PN and EC-Link devices by the modules of a Connect request in the capture")
mcmb2.prefs.heuristic = Pref.bool("Recognise polled uplink headers", true,
    "Decode unknown cyclic frames that start (after the DAP IOPS) with a consistent polled MC-MB2-PN header")
mcmb2.prefs.uplink_timeout = Pref.uint("Uplink watchdog timeout (ms)", 1000,
    "Flag an uplink watchdog that keeps its value longer than this")
mcmb2.prefs.downlink_timeout = Pref.uint("Downlink watchdog timeout (ms)", 2000,
    "Flag a downlink watchdog that keeps its value longer than this (the base shows E010)")

local HEUR_TRIES = 64

------------------------------------------------------------------------
-- Per-capture state
------------------------------------------------------------------------
local by_fid      -- FrameID -> { plan, ... } (plan.sender: Ethernet source Address, or nil = any)
local pending_down -- { { ctl = Address, dev = Address, plan = downlink plan waiting for its FrameID }, ... }
local cm_ports    -- UDP port -> true: controller ports added to udp.port for Connect responses
local tries       -- FrameID -> failed header checks
local devs        -- device key -> analysis state
local frames      -- frame number -> record
local ars         -- AR UUID -> parsed Connect
local table_plans -- plans from the preference table (kept across captures)
local up_limit, down_limit -- watchdog timeouts (s), read from the preferences in init()

local function register(plan)
    if not plan or not plan.fid or plan.fid == 0xFFFF then return end
    if C then fe.pn_frame_id:add(plan.fid, carrier) end
    local t = by_fid[plan.fid]
    if not t then
        t = {}
        by_fid[plan.fid] = t
    end
    for i, p in ipairs(t) do
        if p.sender == plan.sender then -- Addresses compare by value; nil is "any sender"
            t[i] = plan
            return
        end
    end
    t[#t + 1] = plan
end

-- The plan of FrameID `fid` sent by `src`: the one for that sender, else
-- the one for any sender.
local function lookup(t, src)
    local any
    for _, p in ipairs(t) do
        if p.sender == nil then any = p elseif p.sender == src then return p end
    end
    return any
end

local function build_table_plans()
    table_plans = {}
    local entries = layout.parse_table(mcmb2.prefs.layouts)
    for i, e in ipairs(entries) do
        local up, down
        local dev = "pref" .. i
        if e.system == "eclink" then
            up, down = layout.eclink_plans(e.outlen, e.dap, "preference", dev)
        else
            local n = (e.system == "polled") and (e.slots or 4) or 1
            up, down = layout.mcmb2_plans(e.system, n, e.up, e.down, e.dap, "preference", dev)
            if e.system == "polled" and #e.up == 0 then
                -- Sizes come from the header (Y, Z); only the system is forced.
                up.from_header, down.from_header = true, true
            end
        end
        if up and e.in_fid then up.fid = e.in_fid; table_plans[#table_plans + 1] = up end
        if down and e.out_fid then down.fid = e.out_fid; table_plans[#table_plans + 1] = down end
    end
end

-- The C front ends' hooks: which frames the C plugin hands to this plugin.
local function set_hooks()
    if not C then return end
    fe.hook(fe.pn_hook, "candidate", carrier, mcmb2.prefs.heuristic)
    fe.hook(fe.pn_hook, "connect", carrier, mcmb2.prefs.connect)
    fe.hook(fe.pn_hook, "pending", carrier, pending_down ~= nil and #pending_down > 0)
end

function carrier.init()
    for port in pairs(cm_ports or {}) do udp_table:remove(port, carrier) end
    by_fid, pending_down, tries, devs, frames, ars, cm_ports = {}, {}, {}, {}, {}, {}, {}
    if C then fe.pn_frame_id:remove_all(carrier) end
    set_hooks()
    up_limit, down_limit = mcmb2.prefs.uplink_timeout / 1000, mcmb2.prefs.downlink_timeout / 1000
    if not table_plans then build_table_plans() end
    for _, p in ipairs(table_plans) do register(p) end
end

function mcmb2.prefs_changed()
    table_plans = nil
end

------------------------------------------------------------------------
-- Learning from the Connect
------------------------------------------------------------------------
-- A DCE/RPC connectionless PDU (version 4, request or response): the
-- datagrams the carrier hands to the UDP heuristics.
local function is_dcerpc_dg(tvb)
    if tvb:len() < 80 or tvb:range(0, 1):uint() ~= 4 then return false end
    local ptype = tvb:range(1, 1):uint()
    return ptype == 0 or ptype == 2
end

-- The PNIO blocks of an unfragmented Connect request/response (opnum 0) in
-- a DCE/RPC datagram: { { source = tvb, offset = o, value = block type }, ... },
-- and whether it is the request.
local function connect_blocks(tvb)
    if tvb:len() < 80 + 20 then return nil end
    local ptype = tvb:range(1, 1):uint()
    if bit.band(tvb:range(2, 1):uint(), 0x04) ~= 0 then return nil end -- a fragment
    local le = bit.band(tvb:range(4, 1):uint(), 0x10) ~= 0
    local function u16(o) return le and tvb:range(o, 2):le_uint() or tvb:range(o, 2):uint() end
    local function u32(o) return le and tvb:range(o, 4):le_uint() or tvb:range(o, 4):uint() end
    if u16(68) ~= 0 then return nil end -- opnum 0: Connect
    local p = 80
    if ptype == 2 and u32(p) ~= 0 then return nil end -- PNIO status not OK
    local args = u32(p + 4)
    local start, stop = p + 20, math.min(p + 20 + args, tvb:len())
    local list = {}
    while start + 6 <= stop do
        list[#list + 1] = { source = tvb, offset = start, value = tvb:range(start, 2):uint() }
        start = start + 4 + tvb:range(start + 2, 2):uint()
    end
    return list, ptype == 0
end

local function learn_connect(pinfo, blocks)
    local ar = {}
    local any = false
    for _, fi in ipairs(blocks) do
        local v = fi.value
        if v == 0x0101 or v == 0x0102 or v == 0x0104 or v == 0x8101 or v == 0x8102 then
            local src = fi.source
            if src then
                if layout.parse_block(ar, src, fi.offset) then any = true end
            end
        end
    end
    if not any or not ar.uuid then return nil end
    local known = ars[ar.uuid]
    -- The senders of the cyclic frames: the Ethernet addresses of the two
    -- ends of the Connect (compared with those of the cyclic frames).
    if ar.subs then
        -- A request: from the controller to the device.
        ar.ctl_mac, ar.dev_mac = pinfo.dl_src, pinfo.dl_dst
        ar.frame = pinfo.number
        ars[ar.uuid] = ar
        known = ar
    elseif known and (ar.res_fids or ar.dev_mac) then
        known.res_fids = ar.res_fids or known.res_fids
        known.dev_mac = pinfo.dl_src
    else
        return nil
    end
    if not known.subs or not known.iocrs then return nil end
    local cls = layout.classify(known.subs)
    if not cls then return nil end
    local up, down = layout.plans_from_ar(known, cls, "Connect in frame " .. known.frame)
    register(up)
    register(down)
    return { kind = "connect", system = cls.system, up = up, down = down }
end

------------------------------------------------------------------------
-- Helpers
------------------------------------------------------------------------
local function all_zero(ba, objs)
    for _, o in ipairs(objs) do
        for i = o.off, o.off + o.len - 1 do
            if ba:get_index(i) ~= 0 then return false end
        end
    end
    return true
end

local function dev_state(key)
    local d = devs[key]
    if not d then
        d = { up_wd = {}, down_wd = {}, slot_term = {}, hs = eclink_handshake.new() }
        devs[key] = d
    end
    return d
end

-- Splits modules into groups of `size` bytes; nil if they do not add up.
local function group_by(mods, size, count)
    local groups, cur, acc = {}, {}, 0
    if size == 0 then return nil end
    for _, o in ipairs(mods) do
        cur[#cur + 1] = o
        acc = acc + o.len
        if acc == size then
            groups[#groups + 1] = cur
            cur, acc = {}, 0
        elseif acc > size then
            return nil
        end
    end
    if acc ~= 0 or (count and #groups ~= count) then return nil end
    return groups
end

local NO_FINDINGS = {} -- shared by the records without findings; never added to

local function add_finding(rec, anchor, ex, text)
    if rec.findings == NO_FINDINGS then rec.findings = {} end
    rec.findings[#rec.findings + 1] = { anchor = anchor, ex = ex, text = text }
end

-- group_by() for the modules of a plan, cached in the plan (the records
-- share the result and only read it).
local function plan_groups(plan, size, count)
    local cache = plan.groups_cache
    if not cache then
        cache = {}
        plan.groups_cache = cache
    end
    local key = size * 8 + (count or 7)
    local g = cache[key]
    if g == nil then
        g = group_by(plan.modules, size, count) or false
        cache[key] = g
    end
    return g or nil
end

-- The used slots of a polled header as a shared list, by bit mask.
local used_lists = {}
local function used_slots(mask)
    local l = used_lists[mask]
    if not l then
        l = {}
        for k = 1, 4 do if bit.band(mask, bit.lshift(1, k - 1)) ~= 0 then l[#l + 1] = k end end
        used_lists[mask] = l
    end
    return l
end

------------------------------------------------------------------------
-- First pass: the analysis of one cyclic frame
------------------------------------------------------------------------
-- The IOPS and IOCS bytes of a plan, in display order, built once per plan:
-- { off, is_iocs, slot, subslot, label suffix }.
local function ioxs_list(plan)
    local list = plan.ioxs_cache
    if list then return list end
    list = {}
    local function one(off, iocs, slot, subslot)
        list[#list + 1] = { off = off, iocs = iocs, slot = slot, subslot = subslot,
                            suffix = string.format(" (%s of slot %d/0x%x)", iocs and "IOCS" or "IOPS", slot, subslot) }
    end
    for _, o in ipairs(plan.dap) do one(o.off + o.len, false, o.slot, o.subslot) end
    if plan.header then one(plan.header.off + plan.header.len, false, plan.header.slot, 1) end
    if plan.image then one(plan.image.off + plan.image.len, false, plan.image.slot, 1) end
    for _, o in ipairs(plan.modules) do one(o.off + o.len, false, o.slot, o.subslot) end
    for _, c in ipairs(plan.iocs) do one(c.off, true, c.slot, c.subslot) end
    plan.ioxs_cache = list
    return list
end

-- Marks rec.ioxs_bad when an IOPS or IOCS is not GOOD (the tree then shows
-- every one of them); findings for the ones the caller has experts for.
local function check_ioxs(rec, plan, ba, ex_iops, ex_iocs)
    local s, byte = ba.s, string.byte  -- ba is a RawBytes: read its string directly
    for _, x in ipairs(ioxs_list(plan)) do
        local v = byte(s, x.off + 1)
        if v ~= 0x80 then rec.ioxs_bad = true end
        if v ~= 0x80 and (ex_iocs or not x.iocs) then
            add_finding(rec, x.iocs and "iocs" or "iops", x.iocs and ex_iocs or ex_iops, string.format(
                "%s of slot %d/0x%x is %s (0x%02x)", x.iocs and "IOCS" or "IOPS", x.slot, x.subslot,
                IOXS[v] or "not GOOD", v))
        end
    end
end

local function watchdog(rec, st, value, t, frame, limit, ex, what)
    local r = handshake.stall(st, value, t, frame, limit)
    rec.wd_age = t - st.t
    if r and r.kind == "stalled" then
        add_finding(rec, "wd", ex, string.format("%s watchdog unchanged for %.0f ms (value %d since frame %d)%s",
            what, r.age * 1000, r.value, r.since,
            (what == "Uplink") and ": bring the system to a safe state" or ": the base shows E010"))
    end
end

local function analyse_mcmb2(rec, plan, ba, t, frame)
    local d = dev_state(plan.dev)
    local h = plan.header.off
    local up = plan.dir == "up"
    check_ioxs(rec, plan, ba, ef.iops_bad, ef.iocs_bad)
    if plan.system == "duplex" then
        local sb = ba:get_index(h)
        local st = bit.band(sb, 0x0F)
        if up then
            if not DUPLEX_OK[st] then
                add_finding(rec, "status", ef.status_undefined, string.format(
                    "Undefined MC-MB2-PN status 0x%X: bring the system to a safe state", st))
            elseif st ~= 1 then
                add_finding(rec, "status", ef.not_valid, string.format(
                    "%s: no valid terminal data, the IO controller must keep the system in a safe state",
                    STATUS[st]))
            end
            if st ~= 1 and not all_zero(ba, plan.modules) then
                add_finding(rec, "data", ef.data_not_zero, string.format(
                    "Status 0x%X is not 'Terminal present' but the uplink data is not all 0", st))
            end
            watchdog(rec, d.up_wd, ba:get_index(h + 1), t, frame, up_limit,
                ef.uplink_stalled, "Uplink")
        else
            watchdog(rec, d.down_wd, ba:get_index(h + 1), t, frame, down_limit,
                ef.downlink_stalled, "Downlink")
        end
        plan.one_group = plan.one_group or { plan.modules }
        rec.groups = plan.one_group
        return
    end
    -- polled
    local cfg = plan.cfg
    if up then
        local sb = ba:get_index(h)
        local st = bit.band(sb, 0x0F)
        if not POLLED_OK[st] then
            add_finding(rec, "status", ef.status_undefined, string.format(
                "Undefined MC-MB2-PN status 0x%X on a polled system: bring the system to a safe state", st))
        elseif st == 0xA then
            add_finding(rec, "status", ef.not_valid,
                "Fieldbus update failure (E010): no valid terminal data, the IO controller must keep the "
                .. "system in a safe state")
        end
        if bit.band(sb, 0xF0) ~= 0 then
            add_finding(rec, "status", ef.terminal_not_zero, string.format(
                "Terminal number bits are %d, not 0, on a polled system", bit.rshift(sb, 4)))
        end
        watchdog(rec, d.up_wd, ba:get_index(h + 1), t, frame, up_limit,
            ef.uplink_stalled, "Uplink")
        local y, z = ba:get_index(h + 2), ba:get_index(h + 3)
        local mask = 0
        for k = 1, 4 do
            local s = ba:get_index(h + 3 + k)
            if bit.band(s, 0x0F) ~= 0x0F then mask = mask + bit.lshift(1, k - 1) end
        end
        local used = used_slots(mask)
        local groups = plan_groups(plan, y, #used)
        local mismatch = not groups or (not plan.from_header and (y ~= cfg.y or z ~= cfg.z))
        if mismatch then
            add_finding(rec, "size", ef.layout_mismatch, string.format(
                "Y=%d, Z=%d, %d used slot(s) differ from the configured layout (Y=%d, Z=%d, %d slot(s)): "
                .. "bring the system to a safe state", y, z, #used, cfg.y, cfg.z, cfg.n))
            groups = plan_groups(plan, cfg.y) or {}
        end
        rec.groups, rec.slots = groups, used
        d.z, d.used = z, used
        for k = 1, 4 do
            local s = ba:get_index(h + 3 + k)
            local sst, term = bit.band(s, 0x0F), bit.rshift(s, 4)
            local anchor = SLOT_ANCHOR[k]
            if not SLOT_OK[sst] then
                add_finding(rec, anchor, ef.slot_status_undefined, string.format(
                    "Slot %d: undefined terminal status 0x%X: bring the system to a safe state", k, sst))
            end
            if sst ~= 0xF then
                local prev = d.slot_term[k]
                if prev ~= nil and prev ~= term then
                    add_finding(rec, anchor, ef.terminal_changed, string.format(
                        "Slot %d now serves terminal %d (was terminal %d): dynamic polling", k, term, prev))
                end
                d.slot_term[k] = term
                local gi
                for i, u in ipairs(used) do if u == k then gi = i end end
                if sst ~= 1 and gi and groups[gi] and not all_zero(ba, groups[gi]) then
                    add_finding(rec, anchor, ef.data_not_zero, string.format(
                        "Slot %d: terminal status 0x%X is not 'Terminal present' but its uplink data is not all 0",
                        k, sst))
                end
            end
        end
    else
        local r = ba:get_index(h)
        if r ~= 0 then
            add_finding(rec, "reserved", ef.reserved_not_zero, string.format("Reserved byte is 0x%02x, not 0", r))
        end
        watchdog(rec, d.down_wd, ba:get_index(h + 1), t, frame, down_limit,
            ef.downlink_stalled, "Downlink")
        local z = d.z or cfg.z
        local groups = plan_groups(plan, z) or plan_groups(plan, cfg.z) or {}
        local slots = d.used
        if not slots and #groups <= 4 then
            slots = used_slots(bit.lshift(1, #groups) - 1)
        elseif not slots then
            slots = {}
            for i = 1, #groups do slots[i] = i end
        end
        rec.groups, rec.slots = groups, slots
    end
end

local function analyse_eclink(rec, plan, ba, t, frame)
    local d = dev_state(plan.dev)
    local o = plan.image.off
    check_ioxs(rec, plan, ba, eef.iops_bad, nil)
    local inp, out
    if plan.dir == "up" then
        inp = { pci = ba:get_index(o), cci = ba:get_index(o + 1), cai = ba:get_index(o + 3), bu = ba:get_index(o + 20) }
    else
        out = { pco = ba:get_index(o), cco = ba:get_index(o + 1), cao = ba:get_index(o + 3) }
    end
    local r = eclink_handshake.update(d.hs, inp, out, t, frame)
    for _, f in ipairs(r.findings) do add_finding(rec, "image", eef[f[1]], f[2]) end
    rec.pci_age, rec.pco_age = r.pci_age, r.pco_age
end

-- An unknown cyclic FrameID: a polled uplink header, or the downlink that
-- belongs to one seen before (same two MAC addresses, the other way).
local function try_heuristic(fid, tvb, base, size, pinfo)
    if #pending_down > 0 then
        local src, dst = pinfo.dl_src, pinfo.dl_dst
        for i, w in ipairs(pending_down) do
            if w.ctl == src and w.dev == dst and size >= w.plan.need then
                table.remove(pending_down, i)
                set_hooks()
                w.plan.fid = fid
                register(w.plan)
                return w.plan
            end
        end
    end
    local n = tries[fid] or 0
    if n >= HEUR_TRIES then return nil end
    local ba = tvb:range(base, size):bytes()
    local h = layout.polled_header(function(i) return ba:get_index(i) end, size)
    if not h then
        tries[fid] = n + 1
        return nil
    end
    local dev_mac, ctl_mac = pinfo.dl_src, pinfo.dl_dst
    local up, down = layout.mcmb2_plans("polled", h.used, h.up_mods, h.down_mods, h.dap,
        "polled header in frame " .. pinfo.number, "hdr" .. pinfo.number)
    up.fid, up.sender, up.from_header = fid, dev_mac, true
    down.sender, down.from_header = ctl_mac, true
    register(up)
    pending_down[#pending_down + 1] = { ctl = ctl_mac, dev = dev_mac, plan = down }
    set_hooks()
    return up
end

-- The C-SDU as a Lua string with ByteArray's get_index (0-based): one copy
-- per frame instead of a C call per byte read.
local RawBytes = { __index = { get_index = function(self, i) return string.byte(self.s, i + 1) end } }

-- tvb: the PN-RT frame from the FrameID on.
local function first_pass(fid, tvb, pinfo)
    local cands = by_fid[fid]
    local base = 2
    local size = tvb:len() - base - 4
    if size <= 0 then return nil end
    local plan
    if cands then
        plan = lookup(cands, pinfo.dl_src)
    end
    if not plan then
        if not mcmb2.prefs.heuristic or fid < 0x8000 or fid > 0xFBFF then return nil end
        plan = try_heuristic(fid, tvb, base, size, pinfo)
        if not plan then return nil end
    end
    local rec = { plan = plan, base = base, size = size, findings = NO_FINDINGS }
    if size < plan.need then
        add_finding(rec, "top", plan.system == "eclink" and eef.short or ef.short, string.format(
            "C-SDU has %d bytes, the layout needs %d", size, plan.need))
        return rec
    end
    local ba = setmetatable({ s = tvb:raw(base, size) }, RawBytes)
    local t = pinfo.abs_ts
    if plan.system == "eclink" then
        analyse_eclink(rec, plan, ba, t, pinfo.number)
    else
        analyse_mcmb2(rec, plan, ba, t, pinfo.number)
    end
    return rec
end

------------------------------------------------------------------------
-- Display
------------------------------------------------------------------------
local function attach(rec, anchor, item)
    local findings = rec.findings
    if #findings == 0 then return end
    for _, f in ipairs(findings) do
        if f.anchor == anchor then
            item:add_proto_expert_info(f.ex, f.text)
            f.shown = true
        end
    end
end

local function nstime(s)
    return NSTime.new(math.floor(s), math.floor((s % 1) * 1e9 + 0.5))
end

-- The data of several modules as one range (a new data source when they
-- are not contiguous).
local function data_range(tvb, base, objs, name)
    if #objs == 0 then return nil end
    if #objs == 1 then return tvb:range(base + objs[1].off, objs[1].len) end
    local parts = {}
    for i, o in ipairs(objs) do parts[i] = tvb:raw(base + o.off, o.len) end
    return ByteArray.new(table.concat(parts), true):tvb(name):range()
end

-- All GOOD (the usual frame): one item, its label made once per layout.
-- Otherwise one item per IOPS/IOCS byte.
local function add_ioxs(tree, rec, plan, tvb, base, f_iops, f_iocs)
    local list = ioxs_list(plan)
    if not rec.ioxs_bad then
        if not plan.ioxs_good_label then
            plan.ioxs_good_label = string.format("IO status (IOPS / IOCS): all %d GOOD (0x80)", #list)
        end
        tree:add(tvb:range(base, plan.need), plan.ioxs_good_label)
        return
    end
    local sub = tree:add(tvb:range(base, plan.need), "IO status (IOPS / IOCS)")
    for _, x in ipairs(list) do
        sub:add(x.iocs and f_iocs or f_iops, tvb:range(base + x.off, 1)):append_text(x.suffix)
    end
    attach(rec, "iops", sub)
    attach(rec, "iocs", sub)
end

local function show_mcmb2(rec, tvb, pinfo, tree)
    local plan, base = rec.plan, rec.base
    local up = plan.dir == "up"
    local root = tree:add(mcmb2, tvb:range(base, math.min(rec.size, math.max(plan.need, 1))))
    if not plan.title then plan.title = string.format(", %s %s", plan.system, up and "uplink" or "downlink") end
    root:append_text(plan.title)
    root:add(pf.system, plan.system):set_generated()
    root:add(pf.direction, up and "uplink" or "downlink"):set_generated()
    root:add(pf.layout, plan.source):set_generated()
    attach(rec, "top", root)
    pinfo.cols.protocol = "MC-MB2"
    if rec.size < plan.need then
        pinfo.cols.info = "MC-MB2-PN: C-SDU too short for the layout"
        return
    end
    local h = base + plan.header.off
    local info
    local hr, wr = tvb:range(h, 1), tvb:range(h + 1, 1)
    local wdv = wr:uint()
    if up then
        local sb = hr:uint()
        local item = root:add(pf.status, hr)
        local known = (plan.system == "duplex") and DUPLEX_OK or POLLED_OK
        if not known[bit.band(sb, 0x0F)] then item:append_text(" [undefined on a " .. plan.system .. " system]") end
        attach(rec, "status", item)
        if plan.system == "duplex" then
            root:add(pf.terminal, hr)
            local wd = root:add(pf.uplink_watchdog, wr)
            if rec.wd_age then wd:add(pf.watchdog_age, nstime(rec.wd_age)):set_generated() end
            attach(rec, "wd", wd)
            local r = data_range(tvb, base, plan.modules, "MC-MB2 uplink data")
            if r then attach(rec, "data", root:add(pf.uplink_data, r)) end
            if r then iodata.decode("mcmb2.up", -- vrshark_io hook
                { terminal = bit.rshift(sb, 4), frame_id = tvb(0, 2):uint() }, r, root, pinfo) end -- vrshark_io hook
            info = string.format("Uplink duplex: %s, terminal %d, watchdog %d",
                DUPLEX_OK[bit.band(sb, 0x0F)] and STATUS[bit.band(sb, 0x0F)]
                    or string.format("undefined status 0x%X", bit.band(sb, 0x0F)),
                bit.rshift(sb, 4), wdv)
        else
            root:add(pf.terminal, hr)
            local wd = root:add(pf.uplink_watchdog, wr)
            if rec.wd_age then wd:add(pf.watchdog_age, nstime(rec.wd_age)):set_generated() end
            attach(rec, "wd", wd)
            local yr, zr = tvb:range(h + 2, 1), tvb:range(h + 3, 1)
            attach(rec, "size", root:add(pf.uplink_size, yr))
            root:add(pf.downlink_size, zr)
            local parts = {}
            for k = 1, 4 do
                local sr = tvb:range(h + 3 + k, 1)
                local s = sr:uint()
                local sst = bit.band(s, 0x0F)
                local st = root:add(sr, string.format("Slot %d: %s, terminal %d", k,
                    SLOT_STATUS[sst] or string.format("undefined status 0x%X", sst), bit.rshift(s, 4)))
                st:add(pf.slot, k):set_generated()
                st:add(pf.slot_status, sr)
                st:add(pf.slot_terminal, sr)
                local gi
                for i, u in ipairs(rec.slots or {}) do if u == k then gi = i end end
                if gi and rec.groups[gi] then
                    local r = data_range(tvb, base, rec.groups[gi], "MC-MB2 slot " .. k .. " uplink data")
                    if r then st:add(pf.slot_uplink_data, r) end
                    if r then iodata.decode("mcmb2.up", -- vrshark_io hook
                        { terminal = bit.rshift(s, 4), slot = k, frame_id = tvb(0, 2):uint() }, -- vrshark_io hook
                        r, st, pinfo) end -- vrshark_io hook
                end
                attach(rec, SLOT_ANCHOR[k], st)
                if sst ~= 0xF then parts[#parts + 1] = string.format("%d:T%d/%X", k, bit.rshift(s, 4), sst) end
            end
            info = string.format("Uplink polled: status 0x%X, watchdog %d, Y=%d Z=%d, slots %s",
                bit.band(sb, 0x0F), wdv, yr:uint(), zr:uint(), (#parts > 0) and table.concat(parts, " ") or "none")
        end
    else
        if plan.system == "duplex" then
            root:add(pf.base_unit, hr)
        else
            attach(rec, "reserved", root:add(pf.reserved, hr))
        end
        local wd = root:add(pf.downlink_watchdog, wr)
        if rec.wd_age then wd:add(pf.watchdog_age, nstime(rec.wd_age)):set_generated() end
        attach(rec, "wd", wd)
        if plan.system == "duplex" then
            local r = data_range(tvb, base, plan.modules, "MC-MB2 downlink data")
            if r then root:add(pf.downlink_data, r) end
            if r then iodata.decode("mcmb2.down", -- vrshark_io hook
                { frame_id = tvb:range(0, 2):uint() }, r, root, pinfo) end -- vrshark_io hook
            info = string.format("Downlink duplex: base unit %d, watchdog %d", hr:uint(), wdv)
        else
            for i, g in ipairs(rec.groups or {}) do
                local k = rec.slots and rec.slots[i] or i
                local r = data_range(tvb, base, g, "MC-MB2 slot " .. k .. " downlink data")
                if r then
                    local st = root:add(r, string.format("Slot %d", k))
                    st:add(pf.slot, k):set_generated()
                    st:add(pf.slot_downlink_data, r)
                    iodata.decode("mcmb2.down", -- vrshark_io hook
                        { slot = k, frame_id = tvb:range(0, 2):uint() }, r, st, pinfo) -- vrshark_io hook
                end
            end
            info = string.format("Downlink polled: watchdog %d, %d slot(s)", wdv,
                #(rec.groups or {}))
        end
    end
    add_ioxs(root, rec, plan, tvb, base, pf.iops, pf.iocs)
    for _, f in ipairs(rec.findings) do
        if not f.shown then root:add_proto_expert_info(f.ex, f.text) end
        f.shown = nil
    end
    pinfo.cols.info = info
end

local function show_eclink(rec, tvb, pinfo, tree)
    local plan, base = rec.plan, rec.base
    local up = plan.dir == "up"
    local root = tree:add(eclp, tvb:range(base, math.min(rec.size, math.max(plan.need, 1))))
    root:append_text(up and ", input image" or ", output image")
    root:add(epf.layout, plan.source):set_generated()
    attach(rec, "top", root)
    pinfo.cols.protocol = "EC-Link"
    if rec.size < plan.need then
        pinfo.cols.info = "EC-Link: C-SDU too short for the layout"
        return
    end
    local o = plan.image
    local info = image.dissect(tvb, pinfo, root, { kind = up and "input" or "output", offset = base + o.off,
        length = o.len, image_len = o.len })
    iodata.decode_eclink(info, { frame_id = tvb(0, 2):uint() }, pinfo) -- vrshark_io hook
    if rec.pci_age then root:add(epf.pci_age, nstime(rec.pci_age)):set_generated() end
    if rec.pco_age then root:add(epf.pco_age, nstime(rec.pco_age)):set_generated() end
    attach(rec, "image", info and info.item or root)
    add_ioxs(root, rec, plan, tvb, base, epf.iops, epf.iocs)
    for _, f in ipairs(rec.findings) do f.shown = nil end
    pinfo.cols.info = (up and "Input image " or "Output image ") .. ((info and info.summary) or "")
end

local function show_connect(rec, tvb, tree)
    local p = (rec.system == "eclink") and eclp or mcmb2
    local item = tree:add(p, tvb:range(0, 0))
    local function fid(plan)
        if not plan or not plan.fid then return "none" end
        if plan.fid == 0xFFFF then return "assigned in the response" end
        return string.format("0x%04x", plan.fid)
    end
    local text = string.format("%s device: uplink FrameID %s, downlink FrameID %s", rec.system, fid(rec.up),
        fid(rec.down))
    item:append_text(": layout learned, " .. text)
    if p == mcmb2 then
        item:add(pf.system, rec.system):set_generated()
        for _, plan in ipairs({ rec.up or false, rec.down or false }) do
            if plan and plan.fid and plan.fid ~= 0xFFFF then item:add(pf.frame_id, plan.fid):set_generated() end
        end
        item:add_proto_expert_info(ef.learned, "Cyclic data layout learned: " .. text)
    else
        item:add_proto_expert_info(eef.learned, "Cyclic data layout learned: " .. text)
    end
end

------------------------------------------------------------------------
-- The carrier
------------------------------------------------------------------------
local function show(rec, tvb, pinfo, tree)
    if rec.kind == "connect" then
        show_connect(rec, tvb, tree)
    elseif rec.plan.system == "eclink" then
        show_eclink(rec, tvb, pinfo, tree)
    else
        show_mcmb2(rec, tvb, pinfo, tree)
    end
end

-- EtherType 0x8892: Wireshark's PN-RT first, then our cyclic data. With
-- the C front end PN-RT has run already; 0 tells it the frame is not ours;
-- quiet: nobody looks at this frame's tree or columns (first pass only).
local function cyclic(tvb, pinfo, tree, quiet)
    local consumed = 0
    if not C then
        consumed = wrap.call(pn_rt, tvb, pinfo, tree)
        -- a malformed PN-RT frame: Wireshark's report stands, nothing of ours
        if consumed == nil then return tvb:len() end
    end
    local rec
    if pinfo.visited then
        rec = frames[pinfo.number]
    elseif tvb:len() >= 2 then
        local fid = tvb:range(0, 2):uint()
        if by_fid[fid] or (fid >= 0x8000 and fid <= 0xFBFF and mcmb2.prefs.heuristic
                           and ((tries[fid] or 0) < HEUR_TRIES or #pending_down > 0)) then
            rec = first_pass(fid, tvb, pinfo)
            frames[pinfo.number] = rec
        end
    end
    if rec then
        if not quiet then show(rec, tvb, pinfo, tree) end
        if C then return tvb:len() end
    end
    return consumed
end

-- UDP 34964 (and the controllers' ports): the UDP heuristics (DCE/RPC)
-- first, then the Connect blocks.
-- With the C front end DCE/RPC has run already, and it learns the ports.
local function connect(tvb, pinfo, tree)
    if not C then
        if not is_dcerpc_dg(tvb) then return 0 end
        if not DissectorTable.try_heuristics("udp", tvb, pinfo, tree) then return 0 end
    end
    local rec
    if pinfo.visited then
        rec = frames[pinfo.number]
    elseif mcmb2.prefs.connect then
        local blocks, request = connect_blocks(tvb)
        if blocks then
            if not C and request and pinfo.src_port ~= UDP_PNIO_CM and pinfo.src_port ~= ETH_PNRT
                    and not cm_ports[pinfo.src_port] and not udp_table:get_dissector(pinfo.src_port) then
                -- The response comes from the device's own port to this one.
                cm_ports[pinfo.src_port] = true
                udp_table:add(pinfo.src_port, carrier)
            end
            rec = learn_connect(pinfo, blocks)
            frames[pinfo.number] = rec
        end
    end
    if rec then show(rec, tvb, pinfo, tree) end
    return tvb:len()
end

function carrier.dissector(tvb, pinfo, tree)
    -- The C front end calls the "connect" hook for PNIO-CM, the FrameID
    -- table and the "candidate" hook for cyclic frames.
    if C then
        local how = pinfo.match_string
        if how == "connect" then return connect(tvb, pinfo, tree) end
        return cyclic(tvb, pinfo, tree, how == "frame_id.quiet")
    end
    -- No controller port is ever 0x8892 (see connect), so match_uint tells
    -- the two tables apart.
    if pinfo.match_uint == ETH_PNRT then return cyclic(tvb, pinfo, tree) end
    return connect(tvb, pinfo, tree)
end

if C then
    set_hooks()
else
    ethertype_table:add(ETH_PNRT, carrier)
    udp_table:add(UDP_PNIO_CM, carrier)
end
