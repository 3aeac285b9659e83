--[[ mcmb2.lua -- the MC-MB2-PN radio base unit (SP-14-023) in PROFINET IO
cyclic data (protocol "mcmb2").

The carrier (vrshark_pnio.lua) finds the frames and their layout; this file
checks and shows what an MC-MB2-PN sends and receives. Inside the C-SDU
every submodule's data is followed by its IOPS byte; they are shown and
stripped: the data of one terminal is the concatenation of its modules'
data in frame order (SP-14-023 section 5.3: headers first, then per
terminal the data modules, downlink data modules before downlink ASCII
modules; the controllers we know keep that order in the frame).

Duplex/simplex uplink (device -> controller, section 3.1):
  0 status (bits 0-3 status 0,1,2,7,0xA; bits 4-7 terminal) | 1 watchdog | 2.. data
Duplex/simplex downlink (section 3.2):
  0 base unit number | 1 watchdog | 2.. data (none on simplex)
Polled uplink (section 4.1):
  0 status (0xA or 0xF, bits 4-7 zero) | 1 watchdog | 2 Y | 3 Z |
  4..7 slot status (bits 0-3 0,1,2,7,0xF; bits 4-7 terminal) | Y bytes per used slot
Polled downlink (section 4.2):
  0 reserved (0) | 1 watchdog | Z bytes per used slot

The watchdogs (section 2.4), the status values and the slots are checked on
the first pass in frame order, per device, and the findings stored in the
frame's record, so tshark -2 and clicking around show the same as one pass.
The preferences of this protocol also steer the carrier (layout table,
Connect, polled-header recognition).
]]

local dir = debug.getinfo(1, "S").source:match("^@(.*)[/\\]")
package.path = dir .. "/?.luam;" .. package.path
set_plugin_info(require("vrshark.version").info("Cavotec MC-MB2-PN radio base unit in PROFINET IO cyclic data"))
local handshake = require("vrshark.handshake")
local layout = require("vrshark.pnio_layout")
local record = require("vrshark.pnio_record")
local systems = require("vrshark.pnio_systems")
local iodata = require("vrshark.iodata") -- vrshark_io hook
local frontends = require("vrshark.frontends")
local set_cols = frontends.set_cols

local add_finding, attach, nstime = record.add_finding, record.attach, record.nstime
local byte = string.byte
-- (methods called as functions on the per-frame paths: vrshark/api.luam says why)
local api = require("vrshark.api")
local add, range, set_generated, tvb_raw = api.add, api.range, api.set_generated, api.raw

local mcmb2 = systems.mcmb2_proto()

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
-- Slot states in the Info column ("1:T1 present").
local SLOT_SHORT = { [0x0] = "absent", [0x1] = "present", [0x2] = "blocked", [0x7] = "active stop" }
local IOXS = record.IOXS

-- The name of a status value, or "Unknown (0x3)" when `known` does not
-- define it, as Wireshark shows the undefined value of the 4-bit status
-- fields.
local function name_of(names, known, v)
    if known[v] and names[v] then return names[v] end
    return string.format("Unknown (0x%x)", v)
end

------------------------------------------------------------------------
-- Fields
------------------------------------------------------------------------
local pf = {
    system = ProtoField.string("mcmb2.system", "System"),
    direction = ProtoField.string("mcmb2.direction", "Direction"),
    layout = ProtoField.string("mcmb2.layout", "Layout from"),
    layout_entry = ProtoField.string("mcmb2.layout_entry", "Layout table entry (to pin it: mcmb2.layouts)"),
    candidate_setting = ProtoField.string("mcmb2.candidate_setting", "Setting that decodes it"),
    layout_order = ProtoField.string("mcmb2.layout_order", "What the cyclic frames cannot tell of the layout"),
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
    watchdog_ms = ProtoField.uint32("mcmb2.watchdog_ms", "Watchdog unchanged for (ms)"),
    watchdog_since = ProtoField.framenum("mcmb2.watchdog_since", "Watchdog value unchanged since"),
    frame_id = ProtoField.uint16("mcmb2.frame_id", "FrameID", base.HEX),
    -- what the base indicates (SP-14-023 1.5, 2.4): E010, beside the findings
    display = ProtoField.string("mcmb2.display", "Base display (SP-14-023 2.4)"),
    -- a stream that stops, and the PROFINET cycle (vrshark/pnio_stops.luam)
    missing_since = ProtoField.framenum("mcmb2.missing_since", "Last frame of the stream"),
    missing_time = ProtoField.relative_time("mcmb2.missing_time", "No frame of the stream for"),
    lost_frames = ProtoField.uint32("mcmb2.lost_frames", "Frames lost (cycle counter)", base.DEC),
}
mcmb2.fields = pf
-- Statistics > MC-MB2-PN, tshark -z mcmb2,stat (vrshark/health.luam)
require("vrshark.health").register("mcmb2", "MC-MB2-PN", "mcmb2,stat")

-- ProtoExpert.new that remembers the filter names (sparse display)
local expert_names = {}
local function expert_new(name, ...)
    expert_names[name] = true
    return ProtoExpert.new(name, ...)
end

local ef = {
    status_undefined = expert_new("mcmb2.status.undefined",
        "Undefined MC-MB2-PN status: bring the system to a safe state", expert.group.PROTOCOL,
        expert.severity.ERROR),
    slot_status_undefined = expert_new("mcmb2.slot.status.undefined",
        "Undefined terminal status: bring the system to a safe state", expert.group.PROTOCOL,
        expert.severity.ERROR),
    terminal_not_zero = expert_new("mcmb2.terminal.not_zero",
        "Terminal number bits of a polled status byte are not 0", expert.group.PROTOCOL, expert.severity.WARN),
    not_valid = expert_new("mcmb2.no_valid_data",
        "No valid terminal data: the IO controller must keep the system in a safe state",
        expert.group.RESPONSE_CODE, expert.severity.WARN),
    e010 = expert_new("mcmb2.status.e010",
        "Fieldbus update failure (E010) reported by the base: no valid terminal data", expert.group.SEQUENCE,
        expert.severity.ERROR),
    data_not_zero = expert_new("mcmb2.data_not_zero",
        "Status is not 'present' but the uplink data is not all 0", expert.group.PROTOCOL, expert.severity.WARN),
    uplink_stalled = expert_new("mcmb2.uplink_watchdog.stalled",
        "Uplink watchdog unchanged for over 1 s: bring the system to a safe state", expert.group.SEQUENCE,
        expert.severity.ERROR),
    downlink_stalled = expert_new("mcmb2.downlink_watchdog.stalled",
        "Downlink watchdog unchanged for over 2000 ms: the base shows E010", expert.group.SEQUENCE,
        expert.severity.ERROR),
    downlink_unmonitored = expert_new("mcmb2.downlink_watchdog.unwritten",
        "Simplex downlink watchdog not written, the base reports no E010: it may not monitor it (SP-14-023 3.2.2)",
        expert.group.SEQUENCE, expert.severity.NOTE),
    -- SP-14-023 sections 2.4 and 3.1.2: each side increments its watchdog
    -- at least every 500 ms (the stalls above are the other side's timeouts)
    uplink_slow = expert_new("mcmb2.uplink_watchdog.slow",
        "Uplink watchdog not incremented within 500 ms", expert.group.SEQUENCE, expert.severity.WARN),
    downlink_slow = expert_new("mcmb2.downlink_watchdog.slow",
        "Downlink watchdog not incremented within 500 ms", expert.group.SEQUENCE, expert.severity.WARN),
    uplink_back = expert_new("mcmb2.uplink_watchdog.backwards",
        "Uplink watchdog went backwards (a watchdog is only incremented)", expert.group.SEQUENCE,
        expert.severity.WARN),
    downlink_back = expert_new("mcmb2.downlink_watchdog.backwards",
        "Downlink watchdog went backwards (a watchdog is only incremented)", expert.group.SEQUENCE,
        expert.severity.WARN),
    uplink_jump = expert_new("mcmb2.uplink_watchdog.jump",
        "Uplink watchdog moved by more than one", expert.group.SEQUENCE, expert.severity.NOTE),
    downlink_jump = expert_new("mcmb2.downlink_watchdog.jump",
        "Downlink watchdog moved by more than one", expert.group.SEQUENCE, expert.severity.NOTE),
    terminal_changed = expert_new("mcmb2.slot.terminal_changed",
        "Slot changed terminal (dynamic polling)", expert.group.SEQUENCE, expert.severity.NOTE),
    layout_mismatch = expert_new("mcmb2.layout_mismatch",
        "Polled layout (Y/Z/slots) differs from the configured layout: bring the system to a safe state",
        expert.group.PROTOCOL, expert.severity.ERROR),
    iops_bad = expert_new("mcmb2.iops.bad", "IOPS is not GOOD (0x80)", expert.group.PROTOCOL,
        expert.severity.WARN),
    iocs_bad = expert_new("mcmb2.iocs.bad", "IOCS is not GOOD (0x80)", expert.group.PROTOCOL,
        expert.severity.WARN),
    reserved_not_zero = expert_new("mcmb2.reserved.not_zero", "Reserved byte is not 0",
        expert.group.PROTOCOL, expert.severity.WARN),
    short = expert_new("mcmb2.short", "C-SDU shorter than the layout", expert.group.MALFORMED,
        expert.severity.ERROR),
    connect_cut = expert_new("mcmb2.connect_cut",
        "Connect cut by the capture (snaplen): its layout cannot be read", expert.group.MALFORMED,
        expert.severity.NOTE),
    cut = expert_new("mcmb2.cut", "Frame cut by the capture (snaplen): only the bytes captured are decoded",
        expert.group.MALFORMED, expert.severity.NOTE),
    learned = expert_new("mcmb2.layout.learned", "Cyclic data layout learned from this Connect",
        expert.group.SEQUENCE, expert.severity.CHAT),
    inferred = expert_new("mcmb2.layout.inferred", "Cyclic data layout inferred from the cyclic frames",
        expert.group.SEQUENCE, expert.severity.NOTE),
    reopened = expert_new("mcmb2.layout.reopened",
        "Cyclic data layout inferred from the cyclic frames contradicted: the inference is re-opened",
        expert.group.SEQUENCE, expert.severity.WARN),
    ambiguous = expert_new("mcmb2.layout.ambiguous",
        "More than one layout fits these cyclic frames: none is decoded until one is left",
        expert.group.SEQUENCE, expert.severity.NOTE),
    pn_malformed = expert_new("mcmb2.pn_malformed",
        "Malformed to Wireshark's PROFINET dissector, but the layout fits the frame: decoded",
        expert.group.PROTOCOL, expert.severity.NOTE),
    time_backwards = expert_new("mcmb2.time_backwards",
        "Time went backwards (clock step): the watchdog rules restart here", expert.group.SEQUENCE,
        expert.severity.WARN),
    uplink_missing = expert_new("mcmb2.uplink_missing",
        "No uplink frame for over 1 s: the uplink watchdog is not updated, bring the system to a safe state "
        .. "(SP-14-023 3.1.2)", expert.group.SEQUENCE, expert.severity.ERROR),
    downlink_missing = expert_new("mcmb2.downlink_missing",
        "No downlink frame for over 2000 ms: the downlink watchdog is not updated, the base shows E010 "
        .. "(SP-14-023 2.4)", expert.group.SEQUENCE, expert.severity.ERROR),
    data_hold_exceeded = expert_new("mcmb2.data_hold_exceeded",
        "No frame of the stream within the data hold time of the Connect's IOCR: the AR is aborted",
        expert.group.SEQUENCE, expert.severity.ERROR),
    frames_lost = expert_new("mcmb2.frames_lost", "Cyclic frames lost (gap in the PN-RT cycle counter)",
        expert.group.SEQUENCE, expert.severity.WARN),
    candidate = expert_new("mcmb2.candidate",
        "Looks like an MC-MB2-PN base or EC-Link BU whose layout was not inferred: a layout-table entry decodes it",
        expert.group.UNDECODED, expert.severity.NOTE),
}
mcmb2.experts = { ef.status_undefined, ef.slot_status_undefined, ef.terminal_not_zero, ef.not_valid, ef.e010,
                  ef.data_not_zero, ef.uplink_stalled, ef.downlink_stalled, ef.downlink_unmonitored,
                  ef.terminal_changed,
                  ef.layout_mismatch, ef.iops_bad, ef.iocs_bad, ef.reserved_not_zero, ef.short, ef.learned,
                  ef.inferred, ef.ambiguous, ef.pn_malformed, ef.candidate, ef.time_backwards, ef.cut,
                  ef.connect_cut, ef.uplink_slow, ef.downlink_slow, ef.uplink_back, ef.downlink_back,
                  ef.uplink_jump, ef.downlink_jump, ef.reopened, ef.uplink_missing, ef.downlink_missing,
                  ef.data_hold_exceeded, ef.frames_lost }
-- the base's display beside the findings it follows from (SP-14-023 2.4): E010
record.beside[ef.e010] = { pf.display, "E010" }
record.beside[ef.downlink_stalled] = { pf.display, "E010" }

------------------------------------------------------------------------
-- Preferences
------------------------------------------------------------------------
mcmb2.prefs.layouts = Pref.string("Layout table", "",
    "FrameID layouts used when the capture has no Connect, separated by ';'. "
    .. "IN[/OUT]=SYSTEM[:UP[/DOWN]][@DAP], e.g. 0x8001/0x8002=duplex:26/10,a20 ; "
    .. "0x8003/0x8004=polled:4x24/4x2,a8 (a: ASCII modules) ; 0x8005/0x8006=eclink:/224 (see docs/profinet.md)")
mcmb2.prefs.connect = Pref.bool("Learn layouts from the Connect", true,
    "Recognise MC-MB2-PN and EC-Link devices by the modules of a Connect request in the capture")
mcmb2.prefs.heuristic = Pref.bool("Recognise unknown cyclic frames", true,
    "Decode unknown cyclic FrameIDs (0x8000-0xFBFF) that start (after the DAP IOPS) with a consistent polled "
    .. "MC-MB2-PN header, or whose frames leave one duplex, simplex or EC-Link layout (docs/profinet.md)")
mcmb2.prefs.uplink_timeout = Pref.uint("Uplink watchdog timeout (ms)", 1000,
    "Flag an uplink watchdog that keeps its value longer than this")
mcmb2.prefs.downlink_timeout = Pref.uint("Downlink watchdog timeout (ms)", 2000,
    "Flag a downlink watchdog that keeps its value longer than this (the base shows E010)")
-- SP-14-023 3.2.2: a simplex base without multiple-select "may be configured
-- to not monitor the downlink watchdog counter", and its controller then
-- need not write it. Per base: the layout table's +monitored / +unmonitored.
local SIMPLEX_AUTO, SIMPLEX_MONITORED, SIMPLEX_UNMONITORED = 0, 1, 2
mcmb2.prefs.simplex_downlink = Pref.enum("Simplex downlink watchdog", SIMPLEX_AUTO,
    "On a simplex base (downlink header only): auto: a downlink watchdog not seen moving is an error only "
    .. "while the base reports E010, else a note; monitored: always an error (the base monitors it); "
    .. "unmonitored: not checked (the base is configured not to monitor it). A layout-table entry "
    .. "simplex+monitored or simplex+unmonitored sets it for that base",
    { { 1, "auto", SIMPLEX_AUTO }, { 2, "monitored", SIMPLEX_MONITORED },
      { 3, "unmonitored", SIMPLEX_UNMONITORED } }, false)

systems.set_prefs(mcmb2.prefs)

------------------------------------------------------------------------
-- Per-capture state
------------------------------------------------------------------------
local devs        -- device key (plan.dev) -> { up_wd, down_wd, slot_term, z, used }
local up_limit, down_limit -- watchdog timeouts (s), read from the preferences in init()
local simplex_mode, simplex_by_fid -- the preference, and the layout table's per base (downlink FrameID)
local SIMPLEX_OPTION = { monitored = SIMPLEX_MONITORED, unmonitored = SIMPLEX_UNMONITORED }

-- The deadlines of its streams: the watchdog timeouts (SP-14-023 3.1.2,
-- 2.4), a frame that stops coming being a watchdog that is not updated.
local stop_limits = { up = 1, down = 2 }

systems.on_init(function()
    devs = {}
    up_limit, down_limit = mcmb2.prefs.uplink_timeout / 1000, mcmb2.prefs.downlink_timeout / 1000
    stop_limits.up, stop_limits.down = up_limit, down_limit
    simplex_mode, simplex_by_fid = mcmb2.prefs.simplex_downlink, {}
    for _, e in ipairs(layout.parse_table(mcmb2.prefs.layouts)) do
        if e.downlink_watchdog and e.out_fid then simplex_by_fid[e.out_fid] = SIMPLEX_OPTION[e.downlink_watchdog] end
    end
end)

local function dev_state(key)
    local d = devs[key]
    if not d then
        d = { up_wd = {}, down_wd = {}, up_pace = {}, down_pace = {}, slot_term = {} }
        devs[key] = d
    end
    return d
end

------------------------------------------------------------------------
-- Helpers
------------------------------------------------------------------------
local function all_zero(ba, objs) -- ba: a Lua string
    for _, o in ipairs(objs) do
        for i = o.off, o.off + o.len - 1 do
            if byte(ba, i + 1) ~= 0 then return false end
        end
    end
    return true
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
-- ba: the C-SDU as a Lua string (byte i at byte(ba, i + 1)).
-- Seconds rounded to the millisecond (ages are differences of capture
-- times: 1.2 s, not 1.200000048 s).
local function ms(s)
    return math.floor(s * 1000 + 0.5) / 1000
end

local function stalled_text(what, age, value)
    return string.format("%s watchdog unchanged for %.3f s (value %d)%s", what, ms(age), value,
        (what == "Uplink") and ": bring the system to a safe state" or ": the base shows E010")
end

-- The watchdog's age in this frame; past the limit the frame is "stalled"
-- (Info tag on every such frame, the finding on the first).
local function watchdog(rec, st, value, t, frame, limit, ex, what)
    local r = handshake.stall(st, value, t, frame, limit)
    rec.wd_age = ms(t - st.t)
    if t - st.t > limit then rec.wd_since = st.frame end
    if r and r.kind == "stalled" then
        add_finding(rec, "wd", ex, stalled_text(what, r.age, r.value))
    end
end

-- The downlink watchdog of a simplex base (SP-14-023 3.2.2: its controller
-- writes no data, and the base may be configured not to monitor the
-- watchdog). unmonitored: its age only. auto: while it has not been seen
-- moving and the base's last uplink status is not E010 (0xA), a stall is a
-- note naming the setting, with no tag; the error follows on the first
-- frame still stalled once the base reports E010, or on a stall after it
-- has moved. monitored: as any downlink.
local function simplex_watchdog(rec, d, value, t, frame, mode)
    local st = d.down_wd
    if st.value ~= nil and st.value ~= value then d.down_moved, st.noted = true, nil end
    if mode == SIMPLEX_UNMONITORED then
        handshake.stall(st, value, t, frame, math.huge)
        rec.wd_age = ms(t - st.t)
        return
    end
    if mode == SIMPLEX_MONITORED or d.down_moved or d.up_status == 0xA then
        local noted = st.noted
        watchdog(rec, st, value, t, frame, down_limit, ef.downlink_stalled, "Downlink")
        -- noted before, in E010 now: the error the note held back (once)
        if noted and st.flagged and st.value == value and rec.wd_since then
            st.noted = nil
            add_finding(rec, "wd", ef.downlink_stalled, stalled_text("Downlink", t - st.t, value))
        end
        return
    end
    local r = handshake.stall(st, value, t, frame, down_limit)
    rec.wd_age = ms(t - st.t)
    if r and r.kind == "stalled" then
        st.noted = true
        add_finding(rec, "wd", ef.downlink_unmonitored, string.format(
            "Simplex downlink watchdog unchanged for %.3f s (value %d), not seen moving, and the base reports no "
            .. "E010: it may not monitor it (SP-14-023 3.2.2). To decide: mcmb2.simplex_downlink", ms(r.age),
            r.value))
    end
end

-- The pace of a watchdog (SP-14-023 sections 2.4, 3.1.2): incremented by
-- one, at least every 500 ms, by the side that sends it. The frames between
-- two increments repeat the value; a counter that moves faster than the
-- cyclic rate shows steps of more than one (a note: so do lost frames).
local PACE = 0.5
local PACE_TEXT = {
    Uplink = { slow = ef.uplink_slow, back = ef.uplink_back, jump = ef.uplink_jump,
               who = "the base increments it at least every 500 ms" },
    Downlink = { slow = ef.downlink_slow, back = ef.downlink_back, jump = ef.downlink_jump,
                 who = "the IO controller must increment it at least every 500 ms" },
}
local function watchdog_pace(rec, st, value, t, frame, what)
    local r = handshake.pace(st, value, t, frame, PACE, 256)
    if not r then return end
    local p = PACE_TEXT[what]
    -- (a layout inferred from the cyclic frames: a watchdog going back is
    -- evidence against it, vrshark_pnio.lua reopen())
    if r.kind == "back" and rec.plan.inferred then
        rec.contradicts = string.format("%s watchdog went back %d -> %d (SP-14-023 2.4: only incremented, "
            .. "255 wraps to 0)", what:lower(), r.from, r.to)
    end
    if r.kind == "slow" then
        add_finding(rec, "wd", p.slow, string.format("%s watchdog not incremented for %.3f s (value %d): %s",
            what, ms(r.age), r.value, p.who))
    elseif r.kind == "back" then
        add_finding(rec, "wd", p.back, string.format(
            "%s watchdog went back from %d to %d: a watchdog is only incremented (a restart of its sender?)",
            what, r.from, r.to))
    else
        add_finding(rec, "wd", p.jump, string.format(
            "%s watchdog moved from %d to %d (+%d), not by one: incremented faster than the cyclic rate, "
            .. "or frames lost", what, r.from, r.to, r.by))
    end
end

-- The pace of a simplex downlink watchdog: its controller may not write it
-- (SP-14-023 3.2.2), so its pace is only judged once it is known to be
-- written (seen moving, or mcmb2.simplex_downlink says monitored); before
-- that the counter is followed without findings.
local function simplex_pace(rec, d, value, t, frame, mode)
    if mode == SIMPLEX_MONITORED or (mode ~= SIMPLEX_UNMONITORED and d.down_moved) then
        watchdog_pace(rec, d.down_pace, value, t, frame, "Downlink")
    else
        handshake.pace(d.down_pace, value, t, frame, PACE, 256)
    end
end

local function analyse_duplex(rec, d, ba, t, frame)
    local plan = rec.plan
    local h = plan.header.off
    if plan.dir == "up" then
        local sb = byte(ba, h + 1)
        local st = bit.band(sb, 0x0F)
        if not DUPLEX_OK[st] then
            rec.undefined = true
            add_finding(rec, "status", ef.status_undefined, string.format(
                "MC-MB2-PN status %s is undefined: bring the system to a safe state", name_of(STATUS, DUPLEX_OK, st)))
        elseif st == 0xA then
            rec.e010 = true
            add_finding(rec, "status", ef.e010,
                "Fieldbus update failure (E010): no valid terminal data, the IO controller must keep the "
                .. "system in a safe state")
        elseif st ~= 1 then
            rec.no_valid = true
            add_finding(rec, "status", ef.not_valid, string.format(
                "%s: no valid terminal data, the IO controller must keep the system in a safe state",
                STATUS[st]))
        end
        if st ~= 1 and not all_zero(ba, plan.modules) then
            add_finding(rec, "data", ef.data_not_zero, string.format(
                "Status %s is not 'Terminal present' but the uplink data is not all 0",
                name_of(STATUS, DUPLEX_OK, st)))
        end
        watchdog(rec, d.up_wd, byte(ba, h + 2), t, frame, up_limit,
            ef.uplink_stalled, "Uplink")
        watchdog_pace(rec, d.up_pace, byte(ba, h + 2), t, frame, "Uplink")
        d.up_status = st
    elseif #plan.modules == 0 then
        -- simplex: the downlink is its header only
        local mode = simplex_by_fid[plan.fid] or simplex_mode
        simplex_watchdog(rec, d, byte(ba, h + 2), t, frame, mode)
        simplex_pace(rec, d, byte(ba, h + 2), t, frame, mode)
    else
        -- (a layout inferred from the cyclic frames: a base unit number that
        -- moves is evidence against it, SP-14-023 3.2.1: configuration)
        if plan.inferred then
            local bu = byte(ba, h + 1)
            if d.bu ~= nil and d.bu ~= bu then
                rec.contradicts = string.format("base unit number moved %d -> %d (SP-14-023 3.2.1: "
                    .. "configuration)", d.bu, bu)
            end
            d.bu = bu
        end
        watchdog(rec, d.down_wd, byte(ba, h + 2), t, frame, down_limit,
            ef.downlink_stalled, "Downlink")
        watchdog_pace(rec, d.down_pace, byte(ba, h + 2), t, frame, "Downlink")
    end
    plan.one_group = plan.one_group or { plan.modules }
    rec.groups = plan.one_group
end

local function analyse_polled_up(rec, d, ba, t, frame)
    local plan = rec.plan
    local h = plan.header.off
    local cfg = plan.cfg
    local sb = byte(ba, h + 1)
    local st = bit.band(sb, 0x0F)
    if not POLLED_OK[st] then
        rec.undefined = true
        add_finding(rec, "status", ef.status_undefined, string.format(
            "MC-MB2-PN status %s is undefined on a polled system: bring the system to a safe state",
            name_of(STATUS, POLLED_OK, st)))
    elseif st == 0xA then
        rec.e010 = true
        add_finding(rec, "status", ef.e010,
            "Fieldbus update failure (E010): no valid terminal data, the IO controller must keep the "
            .. "system in a safe state")
    end
    if bit.band(sb, 0xF0) ~= 0 then
        add_finding(rec, "status", ef.terminal_not_zero, string.format(
            "Terminal number bits are %d, not 0, on a polled system", bit.rshift(sb, 4)))
    end
    watchdog(rec, d.up_wd, byte(ba, h + 2), t, frame, up_limit,
        ef.uplink_stalled, "Uplink")
    watchdog_pace(rec, d.up_pace, byte(ba, h + 2), t, frame, "Uplink")
    local y, z = byte(ba, h + 3), byte(ba, h + 4)
    local mask = 0
    for k = 1, 4 do
        local s = byte(ba, h + 4 + k)
        if bit.band(s, 0x0F) ~= 0x0F then mask = mask + bit.lshift(1, k - 1) end
    end
    local used = used_slots(mask)
    local groups = plan_groups(plan, y, #used)
    local mismatch = not groups
    if groups and not plan.from_header then
        mismatch = true
        for _, c in ipairs(plan.cfgs) do
            if c.y == y and c.z == z and c.n == #used then mismatch = false end
        end
    end
    if mismatch then
        add_finding(rec, "size", ef.layout_mismatch, string.format(
            "Y=%d, Z=%d, %d used slot(s) differ from the configured layout (Y=%d, Z=%d, %d slot(s)): "
            .. "bring the system to a safe state", y, z, #used, cfg.y, cfg.z, cfg.n))
        groups = plan_groups(plan, cfg.y) or {}
    end
    rec.groups, rec.slots = groups, used
    d.z, d.used = z, used
    for k = 1, 4 do
        local s = byte(ba, h + 4 + k)
        local sst, term = bit.band(s, 0x0F), bit.rshift(s, 4)
        local anchor = SLOT_ANCHOR[k]
        if not SLOT_OK[sst] then
            rec.undefined = true
            add_finding(rec, anchor, ef.slot_status_undefined, string.format(
                "Slot %d: terminal status %s is undefined: bring the system to a safe state", k,
                name_of(SLOT_STATUS, SLOT_OK, sst)))
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
                    "Slot %d: terminal status %s is not 'Terminal present' but its uplink data is not all 0",
                    k, name_of(SLOT_STATUS, SLOT_OK, sst)))
            end
        end
    end
end

local function analyse_polled_down(rec, d, ba, t, frame)
    local plan = rec.plan
    local h = plan.header.off
    local cfg = plan.cfg
    local r = byte(ba, h + 1)
    if r ~= 0 then
        add_finding(rec, "reserved", ef.reserved_not_zero, string.format("Reserved byte is 0x%02x, not 0", r))
    end
    watchdog(rec, d.down_wd, byte(ba, h + 2), t, frame, down_limit,
        ef.downlink_stalled, "Downlink")
    watchdog_pace(rec, d.down_pace, byte(ba, h + 2), t, frame, "Downlink")
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

-- A frame the capture cut (snaplen): the watchdog, when its byte was
-- captured, counts as received; nothing else is read.
local function analyse_cut(rec, d, ba, t, frame)
    local plan = rec.plan
    local h = plan.header.off
    if #ba < h + 2 then return end
    local v = byte(ba, h + 2)
    if plan.dir == "up" then
        watchdog(rec, d.up_wd, v, t, frame, up_limit, ef.uplink_stalled, "Uplink")
        watchdog_pace(rec, d.up_pace, v, t, frame, "Uplink")
    else
        watchdog(rec, d.down_wd, v, t, frame, down_limit, ef.downlink_stalled, "Downlink")
        if plan.system == "duplex" and #plan.modules == 0 then
            simplex_pace(rec, d, v, t, frame, simplex_by_fid[plan.fid] or simplex_mode)
        else
            watchdog_pace(rec, d.down_pace, v, t, frame, "Downlink")
        end
    end
end

local function analyse(rec, ba, t, frame)
    local plan = rec.plan
    local d = dev_state(plan.dev)
    -- (the watchdogs go by a time that never runs backwards: a clock step is a finding)
    local back, prev
    t, back, prev = handshake.clock(d, t, frame)
    if back then
        add_finding(rec, "top", ef.time_backwards, handshake.backwards_text(back, prev, "the watchdog rules"))
    end
    if record.partial(rec) then return analyse_cut(rec, d, ba, t, frame) end
    record.check_ioxs(rec, ba, ef.iops_bad, ef.iocs_bad)
    if plan.system == "duplex" then
        analyse_duplex(rec, d, ba, t, frame)
    elseif plan.dir == "up" then
        analyse_polled_up(rec, d, ba, t, frame)
    else
        analyse_polled_down(rec, d, ba, t, frame)
    end
end

------------------------------------------------------------------------
-- Display
------------------------------------------------------------------------
-- The modules of a list (slot order) in frame order, made once per list:
-- a field's bytes are the frame's bytes in the order the frame holds them,
-- whatever slot order the layout gives them (an inferred layout may take a
-- data module holding text for ASCII, which moves it in the slot order).
local by_offset = setmetatable({}, { __mode = "k" })
local function frame_order(objs)
    local f = by_offset[objs]
    if not f then
        f = {}
        for i, o in ipairs(objs) do f[i] = o end
        table.sort(f, function(a, b) return a.off < b.off end)
        by_offset[objs] = f
    end
    return f
end

-- The data of several modules as one range (a new data source when they
-- are not contiguous).
local function data_range(tvb, base, objs, name)
    if #objs == 0 then return nil end
    if #objs == 1 then return range(tvb, base + objs[1].off, objs[1].len) end
    local parts = {}
    for i, o in ipairs(frame_order(objs)) do parts[i] = tvb:raw(base + o.off, o.len) end
    return ByteArray.new(table.concat(parts), true):tvb(name):range()
end

-- The used slots of a polled uplink and their module groups: k -> group.
local function slot_group(rec, k)
    for i, u in ipairs(rec.slots or {}) do
        if u == k then return rec.groups[i] end
    end
    return nil
end

local function add_watchdog(root, rec, field, wr)
    local wd = add(root, field, wr)
    if rec.wd_age then
        record.add_time(wd, pf.watchdog_age, "Watchdog unchanged for", rec.wd_age, nil, pf.watchdog_ms)
    end
    if rec.wd_since then set_generated(add(wd, pf.watchdog_since, rec.wd_since)) end
    attach(rec, "wd", wd)
end

-- The texts of a slot status byte s of slot k, made once per value
-- (the same few values come frame after frame).
local slot_labels, slot_infos = {}, {}
local function slot_label(k, s)
    local key = k * 256 + s
    local t = slot_labels[key]
    if not t then
        t = string.format("Slot %d: %s, terminal %d", k, name_of(SLOT_STATUS, SLOT_OK, bit.band(s, 0x0F)),
            bit.rshift(s, 4))
        slot_labels[key] = t
    end
    return t
end
local function slot_info(k, s)
    local key = k * 256 + s
    local t = slot_infos[key]
    if not t then
        local sst = bit.band(s, 0x0F)
        t = string.format("%d:T%d %s", k, bit.rshift(s, 4), SLOT_SHORT[sst] or name_of(SLOT_STATUS, SLOT_OK, sst))
        slot_infos[key] = t
    end
    return t
end

-- Decimal text of a byte (a watchdog, a base unit), made once: a number
-- turned into text goes through the C library's floating point printf.
local DEC = {}
for v = 0, 255 do DEC[v] = string.format("%d", v) end

-- The Info text is put together from parts made once per value: the text
-- before the watchdog (by the first header byte), the watchdog, the tags,
-- and what follows: a polled uplink's layout and slots (by the header bytes
-- after the watchdog), a polled downlink's slot count. The watchdog moves on
-- every frame: a memo of whole texts would hold 256 a direction of each base.
-- The long polled uplink text has the tags (info_tags()) right after its
-- watchdog, before the layout and the slots, so that they stay in view
-- where the packet list cuts the line.
local HEADS = {
    up_duplex = function(b1)
        return string.format("Uplink duplex: %s, terminal %d, watchdog ",
            name_of(STATUS, DUPLEX_OK, bit.band(b1, 0x0F)), bit.rshift(b1, 4))
    end,
    up_polled = function(b1)
        return string.format("Uplink polled: %s, watchdog ", name_of(STATUS, POLLED_OK, bit.band(b1, 0x0F)))
    end,
    down_duplex = function(b1) return string.format("Downlink duplex: base unit %d, watchdog ", b1) end,
    down_polled = function() return "Downlink polled: watchdog " end,
}
local heads = { up_duplex = {}, up_polled = {}, down_duplex = {}, down_polled = {} }
-- a polled uplink's text after the tags, by its bytes 3-8 as one number
-- (emptied when full: the slots of many bases)
local TAILS_MAX = 4096
local up_tails, up_tails_n = {}, 0
local down_tails = {}

local function frame_info(rec, tvb, h, tags)
    local plan = rec.plan
    local kind = plan.kind_key
    if not kind then
        kind = ((plan.dir == "up") and "up_" or "down_") .. ((plan.system == "duplex") and "duplex" or "polled")
        plan.kind_key = kind
    end
    local polled_up = kind == "up_polled"
    local b1, b2, b3, b4, b5, b6, b7, b8 = byte(tvb_raw(tvb, h, polled_up and 8 or 2), 1, 8)
    local head = heads[kind][b1]
    if not head then
        head = HEADS[kind](b1)
        heads[kind][b1] = head
    end
    if polled_up then
        local key = b3 + 256 * (b4 + 256 * (b5 + 256 * (b6 + 256 * (b7 + 256 * b8))))
        local tail = up_tails[key]
        if not tail then
            local parts, hb = {}, { b5, b6, b7, b8 }
            for k = 1, 4 do
                if bit.band(hb[k], 0x0F) ~= 0xF then parts[#parts + 1] = slot_info(k, hb[k]) end
            end
            tail = string.format(", Y=%d Z=%d, slots %s", b3, b4, (#parts > 0) and table.concat(parts, ", ") or "none")
            if up_tails_n >= TAILS_MAX then up_tails, up_tails_n = {}, 0 end
            up_tails[key], up_tails_n = tail, up_tails_n + 1
        end
        return head, DEC[b2], tags, tail
    elseif kind == "down_polled" then
        local n = rec.groups and #rec.groups or 0
        local tail = down_tails[n]
        if not tail then
            tail = string.format(", %d slot(s)", n)
            down_tails[n] = tail
        end
        return head, DEC[b2], tail, tags
    end
    return head, DEC[b2], tags, ""
end

-- Protocol and Info: through the C plugin when it calls the decoder (the
-- parts as they are: no new string, no column objects), else pinfo.cols.
local function write_cols(pinfo, a, b, c, d)
    if not (set_cols and set_cols("MC-MB2", a, b, c, d)) then
        local cols = pinfo.cols
        cols.protocol = "MC-MB2"
        cols.info = a .. b .. c .. d
    end
end

local function show_duplex_up(rec, tvb, root, hr, wr, pinfo) -- vrshark_io hook: pinfo
    local sb = hr:uint()
    add(root, pf.terminal, hr)
    add_watchdog(root, rec, pf.uplink_watchdog, wr)
    local r = data_range(tvb, rec.base, rec.plan.modules, "MC-MB2 uplink data")
    if r then attach(rec, "data", add(root, pf.uplink_data, r)) end
    if r and iodata.areas["mcmb2.up"] then iodata.decode("mcmb2.up", -- vrshark_io hook
        { terminal = bit.rshift(sb, 4), frame_id = tvb(0, 2):uint() }, r, root, pinfo) end -- vrshark_io hook
end

local function show_polled_up(rec, tvb, root, h, pinfo) -- vrshark_io hook: pinfo
    local hr, wr = range(tvb, h, 1), range(tvb, h + 1, 1)
    add(root, pf.terminal, hr)
    add_watchdog(root, rec, pf.uplink_watchdog, wr)
    local yr, zr = range(tvb, h + 2, 1), range(tvb, h + 3, 1)
    attach(rec, "size", add(root, pf.uplink_size, yr))
    add(root, pf.downlink_size, zr)
    for k = 1, 4 do
        local sr = range(tvb, h + 3 + k, 1)
        local s = sr:uint()
        local st = add(root, sr, slot_label(k, s))
        set_generated(add(st, pf.slot, k))
        add(st, pf.slot_status, sr)
        add(st, pf.slot_terminal, sr)
        local g = slot_group(rec, k)
        if g then
            local r = data_range(tvb, rec.base, g, "MC-MB2 slot " .. k .. " uplink data")
            if r then add(st, pf.slot_uplink_data, r) end
            if r and iodata.areas["mcmb2.up"] then iodata.decode("mcmb2.up", -- vrshark_io hook
                { terminal = bit.rshift(s, 4), slot = k, frame_id = tvb(0, 2):uint() }, -- vrshark_io hook
                r, st, pinfo) end -- vrshark_io hook
        end
        attach(rec, SLOT_ANCHOR[k], st)
    end
end

local function show_down(rec, tvb, root, hr, wr, pinfo) -- vrshark_io hook: pinfo
    local duplex = rec.plan.system == "duplex"
    if duplex then
        add(root, pf.base_unit, hr)
    else
        attach(rec, "reserved", add(root, pf.reserved, hr))
    end
    add_watchdog(root, rec, pf.downlink_watchdog, wr)
    if duplex then
        local r = data_range(tvb, rec.base, rec.plan.modules, "MC-MB2 downlink data")
        if r then add(root, pf.downlink_data, r) end
        if r and iodata.areas["mcmb2.down"] then -- vrshark_io hook
            iodata.decode("mcmb2.down", { frame_id = tvb(0, 2):uint() }, r, root, pinfo) -- vrshark_io hook
        end -- vrshark_io hook
        return
    end
    for i, g in ipairs(rec.groups or {}) do
        local k = rec.slots and rec.slots[i] or i
        local r = data_range(tvb, rec.base, g, "MC-MB2 slot " .. k .. " downlink data")
        if r then
            local st = add(root, r, string.format("Slot %d", k))
            set_generated(add(st, pf.slot, k))
            add(st, pf.slot_downlink_data, r)
            if iodata.areas["mcmb2.down"] then -- vrshark_io hook
                iodata.decode("mcmb2.down", { slot = k, frame_id = tvb(0, 2):uint() }, r, st, pinfo) -- vrshark_io hook
            end -- vrshark_io hook
        end
    end
end

-- The Info column tags of the findings that matter in the packet list
-- (docs/findings.md "How findings read"): [E010], [no valid data], [watchdog stalled
-- 1.200 s], [undefined].
local function info_tags(rec)
    local tags = ""
    if rec.e010 then tags = tags .. " [E010]" end
    if rec.no_valid then tags = tags .. " [no valid data]" end
    if rec.wd_since then tags = tags .. string.format(" [watchdog stalled %.3f s]", rec.wd_age) end
    if rec.undefined then tags = tags .. " [undefined]" end
    return tags
end

-- A frame the capture cut (snaplen): the header bytes captured, no data.
local function show_cut(rec, tvb, pinfo, root)
    local plan = rec.plan
    local up = plan.dir == "up"
    local h = rec.base + plan.header.off
    local have = rec.cut - plan.header.off
    local wd = ""
    if have >= 1 then
        local hr = range(tvb, h, 1)
        if up then
            attach(rec, "status", add(root, pf.status, hr))
            if plan.system == "duplex" then add(root, pf.terminal, hr) end
        elseif plan.system == "duplex" then
            add(root, pf.base_unit, hr)
        else
            attach(rec, "reserved", add(root, pf.reserved, hr))
        end
    end
    if have >= 2 then
        local wr = range(tvb, h + 1, 1)
        add_watchdog(root, rec, up and pf.uplink_watchdog or pf.downlink_watchdog, wr)
        wd = ", watchdog " .. DEC[wr:uint()]
    end
    record.finish(rec, root)
    write_cols(pinfo, string.format("%s %s: cut by the capture (%d of %d C-SDU bytes)", up and "Uplink" or "Downlink",
        plan.system, rec.cut, rec.size), wd, info_tags(rec), "")
    return root
end

local function show(rec, tvb, pinfo, tree)
    local plan, base = rec.plan, rec.base
    local up = plan.dir == "up"
    if not plan.title then plan.title = string.format(", %s %s", plan.system, up and "uplink" or "downlink") end
    local root = record.root(rec, tvb, tree, mcmb2, plan.title)
    set_generated(add(root, pf.system, plan.system))
    set_generated(add(root, pf.direction, up and "uplink" or "downlink"))
    set_generated(add(root, pf.layout, plan.source))
    if plan.entry then set_generated(add(root, pf.layout_entry, plan.entry)) end
    if plan.order_note then set_generated(add(root, pf.layout_order, plan.order_note)) end
    -- the other layout the frames fit (pnio_infer slot_order()): a setting to apply
    if plan.alt_entry then set_generated(add(root, pf.candidate_setting, "mcmb2.layouts:" .. plan.alt_entry)) end
    add(root, pf.frame_id, range(tvb, 0, 2))
    attach(rec, "top", root)
    if rec.size < plan.need then
        local cols = pinfo.cols
        cols.protocol = "MC-MB2"
        cols.info = "MC-MB2-PN: C-SDU too short for the layout"
        return root
    end
    if record.partial(rec) then return show_cut(rec, tvb, pinfo, root) end
    local h = base + plan.header.off
    local hr, wr = range(tvb, h, 1), range(tvb, h + 1, 1)
    if up then
        local item = add(root, pf.status, hr)
        local known = (plan.system == "duplex") and DUPLEX_OK or POLLED_OK
        if not known[bit.band(hr:uint(), 0x0F)] then
            item:append_text(" [undefined on a " .. plan.system .. " system]")
        end
        attach(rec, "status", item)
        if plan.system == "duplex" then
            show_duplex_up(rec, tvb, root, hr, wr, pinfo) -- vrshark_io hook: pinfo
        else
            show_polled_up(rec, tvb, root, h, pinfo) -- vrshark_io hook: pinfo
        end
    else
        show_down(rec, tvb, root, hr, wr, pinfo) -- vrshark_io hook: pinfo
    end
    record.add_ioxs(root, rec, tvb, pf.iops, pf.iocs)
    record.finish(rec, root)
    write_cols(pinfo, frame_info(rec, tvb, h, info_tags(rec)))
    return root
end

------------------------------------------------------------------------
-- Sparse display: an invisible tree (the packet list, -T fields, -Y)
------------------------------------------------------------------------
-- Wireshark throws away every item of an invisible tree that nobody
-- references, so only the referenced fields are added, each in the
-- occurrences show() gives it (tests/test_sparse_view.py compares both on
-- every capture), flat under the caller's tree; then the findings and the
-- columns when they are wanted. A field without an adder here means show().
-- c: { rec, tvb, tree, plan, up, h = tvb offset of the header }
local function add_at(c, field, off, len) add(c.tree, field, range(c.tvb, off, len)) end

local function polled_up(c) return c.up and c.plan.system ~= "duplex" end
local function polled_down(c) return not c.up and c.plan.system ~= "duplex" end
local function duplex(c) return c.plan.system == "duplex" end

local ADDERS = {
    ["mcmb2.system"] = function(c) add(c.tree, pf.system, c.plan.system) end,
    ["mcmb2.direction"] = function(c) add(c.tree, pf.direction, c.up and "uplink" or "downlink") end,
    ["mcmb2.layout"] = function(c) add(c.tree, pf.layout, c.plan.source) end,
    ["mcmb2.layout_entry"] = function(c) if c.plan.entry then add(c.tree, pf.layout_entry, c.plan.entry) end end,
    ["mcmb2.layout_order"] = function(c)
        if c.plan.order_note then add(c.tree, pf.layout_order, c.plan.order_note) end
    end,
    ["mcmb2.status"] = function(c) if c.up then add_at(c, pf.status, c.h, 1) end end,
    ["mcmb2.terminal"] = function(c) if c.up then add_at(c, pf.terminal, c.h, 1) end end,
    ["mcmb2.uplink_watchdog"] = function(c) if c.up then add_at(c, pf.uplink_watchdog, c.h + 1, 1) end end,
    ["mcmb2.downlink_watchdog"] = function(c) if not c.up then add_at(c, pf.downlink_watchdog, c.h + 1, 1) end end,
    ["mcmb2.watchdog_age"] = function(c)
        if c.rec.wd_age then add(c.tree, pf.watchdog_age, nstime(c.rec.wd_age)) end
    end,
    ["mcmb2.watchdog_ms"] = function(c)
        if c.rec.wd_age then add(c.tree, pf.watchdog_ms, record.whole_ms(c.rec.wd_age)) end
    end,
    ["mcmb2.watchdog_since"] = function(c)
        if c.rec.wd_since then add(c.tree, pf.watchdog_since, c.rec.wd_since) end
    end,
    ["mcmb2.uplink_data"] = function(c)
        if c.up and duplex(c) then
            local r = data_range(c.tvb, c.rec.base, c.plan.modules, "MC-MB2 uplink data")
            if r then add(c.tree, pf.uplink_data, r) end
        end
    end,
    ["mcmb2.downlink_data"] = function(c)
        if not c.up and duplex(c) then
            local r = data_range(c.tvb, c.rec.base, c.plan.modules, "MC-MB2 downlink data")
            if r then add(c.tree, pf.downlink_data, r) end
        end
    end,
    ["mcmb2.uplink_size"] = function(c) if polled_up(c) then add_at(c, pf.uplink_size, c.h + 2, 1) end end,
    ["mcmb2.downlink_size"] = function(c) if polled_up(c) then add_at(c, pf.downlink_size, c.h + 3, 1) end end,
    ["mcmb2.base_unit"] = function(c) if not c.up and duplex(c) then add_at(c, pf.base_unit, c.h, 1) end end,
    ["mcmb2.reserved"] = function(c) if polled_down(c) then add_at(c, pf.reserved, c.h, 1) end end,
    ["mcmb2.slot"] = function(c)
        if polled_up(c) then
            for k = 1, 4 do add(c.tree, pf.slot, k) end
        elseif polled_down(c) then
            for i, g in ipairs(c.rec.groups or {}) do
                if #g > 0 then add(c.tree, pf.slot, c.rec.slots and c.rec.slots[i] or i) end
            end
        end
    end,
    ["mcmb2.slot.status"] = function(c)
        if polled_up(c) then for k = 1, 4 do add_at(c, pf.slot_status, c.h + 3 + k, 1) end end
    end,
    ["mcmb2.slot.terminal"] = function(c)
        if polled_up(c) then for k = 1, 4 do add_at(c, pf.slot_terminal, c.h + 3 + k, 1) end end
    end,
    ["mcmb2.slot.uplink_data"] = function(c)
        if not polled_up(c) then return end
        for k = 1, 4 do
            local g = slot_group(c.rec, k)
            if g then
                local r = data_range(c.tvb, c.rec.base, g, "MC-MB2 slot " .. k .. " uplink data")
                if r then add(c.tree, pf.slot_uplink_data, r) end
            end
        end
    end,
    ["mcmb2.slot.downlink_data"] = function(c)
        if not polled_down(c) then return end
        for i, g in ipairs(c.rec.groups or {}) do
            local k = c.rec.slots and c.rec.slots[i] or i
            local r = data_range(c.tvb, c.rec.base, g, "MC-MB2 slot " .. k .. " downlink data")
            if r then add(c.tree, pf.slot_downlink_data, r) end
        end
    end,
    ["mcmb2.iops"] = function(c) record.add_ioxs_sparse(c.tree, c.rec, c.tvb, pf.iops, false) end,
    ["mcmb2.iocs"] = function(c) record.add_ioxs_sparse(c.tree, c.rec, c.tvb, pf.iocs, true) end,
    ["mcmb2.frame_id"] = function(c) add(c.tree, pf.frame_id, range(c.tvb, 0, 2)) end,
    -- (a candidate's note, always shown whole; and the other layout a
    -- settled one offers)
    ["mcmb2.candidate_setting"] = function(c)
        if c.plan.alt_entry then add(c.tree, pf.candidate_setting, "mcmb2.layouts:" .. c.plan.alt_entry) end
    end,
}
local SPARSE = { adders = ADDERS, experts = expert_names, prefixes = { "mcmb2", "vrshark_io", "vrshark.io" } }

-- false: show() is needed instead. One context table, refilled per frame.
local ctx = {}
local function sparse(rec, tvb, pinfo, tree, view)
    local plan = rec.plan
    local p = frontends.plan(view, SPARSE)
    if not p or rec.size < plan.need or rec.cut then return false end
    -- machine data can add findings and Info tags of its own
    if (p.cols or p.experts) and (iodata.areas["mcmb2.up"] or iodata.areas["mcmb2.down"]) then return false end
    local h = rec.base + plan.header.off
    -- (a tap that walks the tree's top level, -z io,phs, counts the protocol)
    if p.protos then record.root(rec, tvb, tree, mcmb2, "") end
    if #p.adders > 0 then
        local c = ctx
        c.rec, c.tvb, c.tree, c.plan, c.up, c.h = rec, tvb, tree, plan, plan.dir == "up", h
        local adders = p.adders
        for i = 1, #adders do adders[i](c) end
    end
    if p.experts then record.finish(rec, tree) end
    if p.cols then write_cols(pinfo, frame_info(rec, tvb, h, info_tags(rec))) end
    return true
end

local function show_connect(rec, tvb, tree, text)
    local item = tree:add(mcmb2, tvb:range(0, 0))
    item:append_text(": layout learned, " .. text)
    item:add(pf.system, rec.system):set_generated()
    for _, plan in ipairs({ rec.up or false, rec.down or false }) do
        if plan and plan.fid and plan.fid ~= 0xFFFF then item:add(pf.frame_id, plan.fid):set_generated() end
    end
    item:add_proto_expert_info(ef.learned, "Cyclic data layout learned: " .. text)
end

-- Cyclic frames of a run that looked like ours but whose layout was not
-- inferred (vrshark_pnio.lua candidate()): the note and the settings that
-- decode it; on the frame that found more than one layout fitting
-- equally, that too (nothing is decoded until one is left).
local function show_candidate(rec, tvb, tree)
    local item = tree:add(mcmb2, tvb:range(0, 0))
    item:append_text(": " .. (rec.head or "looks like ours, layout not inferred"))
    for _, s in ipairs(rec.settings) do item:add(pf.candidate_setting, s):set_generated() end
    item:add_proto_expert_info(rec.reopened and ef.reopened or ef.candidate, rec.text)
    if rec.ambiguous then
        item:add_proto_expert_info(ef.ambiguous, "Layouts that fit these cyclic frames equally: " .. rec.ambiguous
            .. "; none is decoded until one is left (or pin one in mcmb2.layouts)")
    end
end

-- A DCE/RPC datagram the capture cut that may be a Connect
-- (vrshark_pnio.lua cut_datagram()).
local function show_cut_connect(rec, tvb, tree)
    local item = tree:add(mcmb2, tvb:range(0, 0))
    item:append_text(": Connect cut by the capture, layout not read")
    item:add_proto_expert_info(ef.connect_cut, rec.text)
end

local dec = { proto = mcmb2, short = ef.short, cut = ef.cut, inferred = ef.inferred,
                                          reopened = ef.reopened,
                                          pn_malformed = ef.pn_malformed,
                                          per_frame = { up = "wd_age", down = "wd_age" },
                                          analyse = analyse, show = show, sparse = sparse,
                                          show_connect = show_connect, show_candidate = show_candidate,
                                          show_cut_connect = show_cut_connect }
dec.stops = require("vrshark.pnio_stops").watcher({ proto = mcmb2, dec = dec,
    ef = { up = ef.uplink_missing, down = ef.downlink_missing, hold = ef.data_hold_exceeded, lost = ef.frames_lost },
    pf = { since = pf.missing_since, time = pf.missing_time, lost = pf.lost_frames },
    names = { up = "uplink", down = "downlink" }, limits = stop_limits,
    texts = { up = "the uplink watchdog is not updated, bring the system to a safe state (SP-14-023 3.1.2)",
              down = "the downlink watchdog is not updated, the base shows E010 (SP-14-023 2.4)" } })
systems.register({ "duplex", "polled" }, dec)
