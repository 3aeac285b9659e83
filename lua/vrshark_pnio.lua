--[[ vrshark_pnio.lua -- the carrier of our systems in PROFINET IO (protocol
"vrshark_pnio"): finds the cyclic frames of MC-MB2-PN bases (decoded by
mcmb2.lua) and EC-Link BUs (decoded by eclink_pnio.lua) and learns where
their data sit.

Transport: PROFINET RT, EtherType 0x8892 (optionally 802.1Q tagged):

  FrameID (2) | C-SDU (40..1440) | CycleCounter (2) | DataStatus (1) | TransferStatus (1)

Wireshark's own pn_rt/pn_io dissectors decode the frame as always, before
the carrier sees it. The carrier has one entry for a cyclic frame (cyclic())
and one for a Connect request/response (DCE/RPC over UDP, PNIO-CM:
connect(), cut_datagram()), and never asks which mode it runs in: its
transport, `front` (vrshark/transport.luam pnio()), is chosen once at load.
With the C front ends of the C plugin (vrshark/frontends.luam), the C plugin
is the protocol "vrshark_pnio": it runs PN-RT and DCE/RPC itself and calls
the carrier only for the FrameIDs it was given (front.watch), for candidate
FrameIDs while mcmb2.heuristic is on (the "candidate" hook: a polled
header, or a layout inferred from the cyclic frames; the "pending" flag)
and for Connects ("connect" hook; while the "response" flag says no AR
learned from a request is held, no response on the first pass, and no
request whose expected submodules were refused before): front.hooks. The
carrier then runs under the Proto of mcmb2 (the C plugin owns the name).
Without the C plugin the transport is the protocol "vrshark_pnio": it takes
EtherType 0x8892 and UDP port 34964 (and, for the response coming from the
device's own port, the controller's port learned from the request), calls
PN-RT or the UDP heuristics first, and hands the frame to the same entries
(an unknown FrameID costs a table lookup). The blocks of a Connect are read
from the bytes. Other traffic never reaches the plugin.

Layouts (vrshark/pnio_layout.luam) come from, best first:
  1. the Connect request/response in the capture (IOCR blocks give FrameIDs
     and frame offsets, ExpectedSubmodule blocks the lengths);
  2. the preference table (mcmb2.layouts, format in docs/profinet.md and
     vrshark/pnio_layout.luam);
  3. a polled MC-MB2-PN uplink header, which describes itself (Y, Z, slot
     status); the downlink from the controller to the same device is laid
     out with it;
  4. the cyclic frames of a duplex/simplex MC-MB2-PN base or an EC-Link BU
     themselves (vrshark/pnio_infer.luam): a run of frames of one FrameID
     pair, whose IOxS positions, module sizes, watchdogs or EC-Link images
     leave one layout, wherever the controller put the IO data objects and
     IOCS in the frame. Its frames before the settling frame are analysed
     then, in frame order: shown on the second pass (tshark -2, the GUI).
     A run that looked like ours but did not settle carries the candidate
     note with the layout-table entries that decode it (candidate()); so
     do the frames of a layout re-opened (reopen()) whose runs were then
     given up, naming the re-opening frame and the entry it had.

The decoders register themselves in vrshark/pnio_systems.luam by system
("duplex", "polled", "eclink"); the per-frame record they fill is described
in vrshark/pnio_record.luam. Everything runs on the first pass in frame order
and is stored per frame, so tshark -2 and clicking around show the same as
one pass.
]]

local dir = debug.getinfo(1, "S").source:match("^@(.*)[/\\]")
package.path = dir .. "/?.luam;" .. package.path
set_plugin_info(require("vrshark.version").info(
    "PROFINET IO carrier of MC-MB2-PN and EC-Link cyclic frames (layouts from Connect, table, polled header)"))
local layout = require("vrshark.pnio_layout")
local infer = require("vrshark.pnio_infer")
local record = require("vrshark.pnio_record")
local systems = require("vrshark.pnio_systems")
-- (methods called as functions: vrshark/api.luam says why)
local api = require("vrshark.api")
local tvb_len, tvb_raw, tvb_reported_len = api.len, api.raw, api.reported_len
-- (the pinfo attributes read on every cyclic frame)
local p_number, p_visited, p_abs_ts, p_dl_src, p_dl_dst = api.pinfo.number, api.pinfo.visited, api.pinfo.abs_ts,
    api.pinfo.dl_src, api.pinfo.dl_dst
local seam = require("vrshark.seam")
-- (the clock of streams that stop, ticked by the transport on every frame the carrier sees)
local deadlines = require("vrshark.deadlines")
local stops = require("vrshark.pnio_stops")
-- (frames and per_frame by frame number: vrshark/framemap.luam says why)
local framemap = require("vrshark.framemap")
local passes = require("vrshark.passes")
local health = require("vrshark.health") -- Statistics > MC-MB2-PN, EC-Link
local fget, fset = framemap.get, framemap.set

-- The transport, in the mode the plugin runs in (vrshark/transport.luam
-- says what each method does in each); the carrier's Proto is the
-- transport's (mcmb2's with the C front ends, which own the name "vrshark_pnio").
local mcmb2_proto = systems.mcmb2_proto()
local front = require("vrshark.transport").pnio()
local carrier = front.proto
local view_for = front.view_for

-- Failed polled-header checks per unknown FrameID before it is given up
-- (the C front end's bound of candidate refusals too).
local HEUR_TRIES = seam.PN_CANDIDATE_TRIES

------------------------------------------------------------------------
-- Per-capture state
------------------------------------------------------------------------
-- Everything the carrier learns from one capture, all of it made anew by
-- new_capture() when a file starts (init()), nothing else kept across
-- files. Plain upvalues, not one table: the cyclic path reads by_fid,
-- frames, once and spare on every frame. What else a file start resets:
-- the clock (deadlines.reset), the streams (stops.reset), the statistics
-- (health.reset), the transport's own (vrshark/transport.luam on_init:
-- EtherType and controller ports), each decoder its per-device state (the
-- init of its Proto).
--
-- layouts     by_fid       FrameID -> { plan, ... } (plan.sender: Ethernet source Address, or nil = any)
--             noted_fid    FrameID -> true: watched for a polled downlink's note (down_note())
--             pending_down { { ctl = Address, dev = Address, plan = downlink plan waiting for its FrameID }, ... }
--             tries        FrameID -> failed header checks
-- Connect     ars          AR UUID -> parsed Connect
--             not_ours     expected submodule blocks (connect_blocks' key) -> true: no system of ours
--             frags        fragments of Connects being put together (defragment())
--             cut_connect  the first DCE/RPC datagram that may be a Connect the capture cut
--                          (cut_datagram()), or nil
-- inference   runs         vrshark.pnio_infer state: the runs of FrameIDs without a layout
--             gone         FrameID -> { src, dst, src, dst, ... }: Ethernet Addresses of its runs given up
--                          (gave_up())
--             addr_of      station key of pnio_infer (tostring of an Ethernet address) -> Address
--             hint_recs    hint of pnio_infer -> the record of its candidate frames
--             reopening    FrameID -> the note of its frames while a layout re-opened is inferred again, or
--                          given up (one pass)
--             unsettled    second pass: whether a run was left unsettled (nil: not asked yet)
-- records     frames       frame number -> record (shared by frames that analyse alike: shared_record),
--                          vrshark.framemap
--             per_frame    frame number -> the decoder's per_frame value or false, vrshark.framemap; n: highest
--                          filled
--             last_rec     plan -> its latest distinct records (shared_record)
--             spare        an emptied record table for the next frame (new_record), or nil
--             once         true in a one-pass tshark run (vrshark/passes.luam): no frame is shown again, so a
--                          cyclic frame's record is not kept (with no finding, its table is the next frame's)
-- preferences heuristic, learn   mcmb2.heuristic and mcmb2.connect (also read at load, for the hooks)
local by_fid, noted_fid, by_carrier, pending_down, tries
local ars, not_ours, frags, cut_connect
local runs, gone, addr_of, hint_recs, reopening, unsettled
local frames, per_frame, last_rec, spare
local once = false
local heuristic, learn

local function new_capture()
    by_fid, noted_fid, by_carrier, pending_down, tries = {}, {}, {}, {}, {}
    ars, not_ours, frags, cut_connect = {}, {}, {}, nil
    runs, gone, addr_of, hint_recs, reopening, unsettled = infer.new(), {}, {}, {}, {}, nil
    -- (packed: vrshark/framemap.luam says why; the ages are rounded to the ms)
    frames, per_frame = framemap.packed_refs(), framemap.packed_ms()
    last_rec, per_frame.n, spare = {}, 0, nil
    once = passes.once()
    local prefs = systems.prefs()
    heuristic, learn = prefs.heuristic, prefs.connect
end

-- A FrameID the C front end hands to the carrier's Proto on every pass:
-- one the inference or a note needs, whatever its layouts (by_carrier).
local function watch_carrier(fid)
    by_carrier[fid] = true
    front.watch(fid)
end

-- The Proto the C front end hands FrameID fid's frames to (its layouts t):
-- the decoder's own when every layout is of one decoder with a Proto not
-- the carrier's (eclink_pnio), so that its frames are dissected under it
-- without a call through() each (pnio_systems.set_entry()); else the
-- carrier's (nil).
local function entry_proto(fid, t)
    if by_carrier[fid] then return nil end
    local as
    for _, p in ipairs(t) do
        local dec = systems.decoder(p.system)
        local proto = dec and dec.proto
        if not proto or proto == carrier or (as and as ~= proto) then return nil end
        as = proto
    end
    return as
end

local function register(plan)
    if not plan or not plan.fid or plan.fid == 0xFFFF then return end
    local t = by_fid[plan.fid]
    if not t then
        t = {}
        by_fid[plan.fid] = t
    end
    local at = #t + 1
    for i, p in ipairs(t) do
        if p.sender == plan.sender then -- Addresses compare by value; nil is "any sender"
            at = i
            break
        end
    end
    t[at] = plan
    front.watch(plan.fid, entry_proto(plan.fid, t))
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

-- The plans of the layout table preference. A polled entry without sizes
-- gives placeholders ("deferred"): the frames of its FrameIDs are laid out
-- by their polled header, as the heuristic does, but whatever the
-- preference mcmb2.heuristic says.
local function table_plans(text)
    local plans = {}
    local entries = layout.parse_table(text)
    for i, e in ipairs(entries) do
        local up, down
        local dev = "pref" .. i
        if e.system == "eclink" then
            up, down = layout.eclink_plans(e.outlen, e.dap, "preference", dev, e.order)
        elseif e.system == "polled" and #e.up == 0 then
            up = { system = "polled", dir = "up", deferred = true, out_fid = e.out_fid or nil }
            down = { system = "polled", dir = "down", deferred = true }
        else
            local n = (e.system == "polled") and (e.slots or 4) or 1
            up, down = layout.mcmb2_plans(e.system, n, e.up, e.down, e.dap, "preference", dev, e.order, e.ascii)
        end
        if up and e.in_fid then up.fid = e.in_fid; plans[#plans + 1] = up end
        if down and e.out_fid then down.fid = e.out_fid; plans[#plans + 1] = down end
    end
    return plans
end

-- Which frames the C front ends hand to the carrier, as its state says
-- (front.hooks; without them every frame reaches it).
local function set_hooks()
    front.hooks(heuristic, learn, (pending_down ~= nil and #pending_down > 0) or (runs ~= nil and infer.alive(runs)),
        ars ~= nil and next(ars) ~= nil)
end

-- Connect responses are read only for an AR learned from its request: the
-- C front end hands them over while the flag FLAG_PN_RESPONSE says one is held.
local function ars_changed(had)
    if had ~= (next(ars) ~= nil) then set_hooks() end
end

local function init()
    deadlines.reset()
    stops.reset()
    new_capture()
    health.reset()
    front.forget_all()
    set_hooks()
    for _, p in ipairs(table_plans(systems.prefs().layouts)) do register(p) end
end
front.on_init(init)

------------------------------------------------------------------------
-- Learning from the Connect
------------------------------------------------------------------------
-- The blocks read, and (true) those read first: the AR and the expected
-- submodules of a request, the AR of a response. A Connect not of ours
-- stops there (its submodules are no system of ours, or the response's AR
-- is not known): its IOCRs, hundreds of entries on a large device, are
-- never read.
local BLOCKS = { [0x0101] = true, [0x0104] = true, [0x8101] = true, [0x0102] = false, [0x8102] = false }

-- A number of n (2 or 4) bytes at (0-based) offset o of the string h,
-- little-endian when le (the DCE/RPC header's byte order). (One call to
-- string.byte: each Connect is read this way.)
local function num(h, o, n, le)
    local a, b, c, d = string.byte(h, o + 1, o + n)
    if n == 2 then
        if le then return b * 256 + a end
        return a * 256 + b
    end
    if le then return ((d * 256 + c) * 256 + b) * 256 + a end
    return ((a * 256 + b) * 256 + c) * 256 + d
end

-- The PNIO blocks of an unfragmented Connect request/response (opnum 0) in
-- a DCE/RPC datagram (the string s; defragment() puts a fragmented one
-- together) that learn_connect() reads (BLOCKS), as s and, flat, each
-- block's type and first and last index in it: { s = the string, type1,
-- first1, last1, type2, ..., n = 3 x the blocks (entries after the nth are
-- left from an earlier Connect), key = the expected submodule blocks as one
-- string (the key of not_ours; a controller connects the same devices
-- again and again) }, and whether it is the request. No block is copied
-- out here: a Connect of no system of ours (not_ours) or a response to an
-- AR not learned is done with after its AR block, and each string made is
-- memory the collector walks later. The list is one table, emptied for
-- each Connect (learn_connect keeps nothing of it).
local blocks_scratch = {}

local function connect_blocks(s)
    local tlen = #s
    if tlen < 80 + 20 then return nil end
    local ptype = string.byte(s, 2)
    local le = bit.band(string.byte(s, 5), 0x10) ~= 0
    if string.byte(s, 69) + string.byte(s, 70) ~= 0 then return nil end -- opnum 0: Connect
    local p = 80
    if ptype == 2 and num(s, p, 4, le) ~= 0 then return nil end -- PNIO status not OK
    local args = num(s, p + 4, 4, le)
    local list, n = blocks_scratch, 0
    local kfirst, klast, parts -- the 0x0104 blocks: one run of them, or parts
    -- i: the 1-based index of the block in s; the blocks end at `stop`
    local i, stop = p + 21, math.min(p + 20 + args, tlen)
    while i + 5 <= stop do
        local t1, t2, l1, l2 = string.byte(s, i, i + 3)
        local t = t1 * 256 + t2
        local last = i + 3 + l1 * 256 + l2
        -- (a block that runs past the datagram is not read)
        if BLOCKS[t] ~= nil and last <= tlen then
            list[n + 1], list[n + 2], list[n + 3] = t, i, last
            n = n + 3
            if t == 0x0104 then
                if klast == i - 1 and not parts then
                    klast = last
                elseif not kfirst then
                    kfirst, klast = i, last
                else
                    parts = parts or { string.sub(s, kfirst, klast) }
                    parts[#parts + 1] = string.sub(s, i, last)
                end
            end
        end
        i = last + 1
    end
    list.s, list.n = s, n
    list.key = parts and table.concat(parts) or (kfirst and string.sub(s, kfirst, klast))
    return list, ptype == 0
end

-- A Connect large enough (many submodules) is sent as several DCE/RPC
-- datagrams, each with the fragment flag, its number and the same
-- activity, sequence number and packet type. s: one datagram as a string.
-- Returns s when it is no fragment; for a fragment, the datagram put
-- together (the first fragment's header without the fragment flags, the
-- bodies in order) once every fragment up to the last is there, else nil.
-- Fragments are kept until their datagram is whole (or the next file);
-- one sent again replaces its copy.
local FRAG, LASTFRAG = 0x04, 0x02
local function defragment(s)
    if #s < 80 then return nil end
    local flags = string.byte(s, 3)
    if bit.band(flags, FRAG) == 0 then return s end
    local le = bit.band(string.byte(s, 5), 0x10) ~= 0
    local key = string.sub(s, 41, 56) .. string.sub(s, 65, 68) .. string.sub(s, 2, 2)
    local fragnum, len = num(s, 76, 2, le), num(s, 74, 2, le)
    local f = frags[key]
    if not f then
        f = {}
        frags[key] = f
    end
    f[fragnum] = string.sub(s, 81, 80 + len)
    if fragnum == 0 then
        f.head = string.sub(s, 1, 2) .. string.char(bit.band(flags, 0xFF - FRAG - LASTFRAG)) .. string.sub(s, 4, 80)
    end
    if bit.band(flags, LASTFRAG) ~= 0 then f.last = fragnum end
    if not (f.head and f.last) then return nil end
    local parts = { f.head }
    for i = 0, f.last do
        if not f[i] then return nil end
        parts[#parts + 1] = f[i]
    end
    frags[key] = nil
    return table.concat(parts)
end

local function learn_connect(pinfo, blocks)
    local key = blocks.key
    -- A Connect of devices known not to be ours: read further only to
    -- forget an AR of ours it replaces (none held: nothing to read).
    if key and not_ours[key] and next(ars) == nil then return nil end
    local ar = {}
    local any = false
    local s = blocks.s
    local function parse(first)
        for j = 1, blocks.n, 3 do
            local t = blocks[j]
            if BLOCKS[t] == first and not (key and not_ours[key] and t == 0x0104)
                    and layout.parse_block(ar, string.sub(s, blocks[j + 1], blocks[j + 2])) then
                any = true
            end
        end
    end
    parse(true)
    if not ar.uuid then return nil end
    local cls
    local had = next(ars) ~= nil
    if key and not_ours[key] then
        ars[ar.uuid] = nil -- (a new Connect of the AR replaces the one before)
        ars_changed(had)
        return nil
    elseif ar.subs then
        cls = layout.classify(ar.subs)
        if not cls then
            if key then not_ours[key] = true end
            ars[ar.uuid] = nil
            ars_changed(had)
            return nil
        end
    elseif not ars[ar.uuid] then
        return nil
    end
    parse(false)
    if not any then return nil end
    local known = ars[ar.uuid]
    -- The senders of the cyclic frames: the Ethernet addresses of the two
    -- ends of the Connect (compared with those of the cyclic frames).
    if ar.subs then
        -- A request: from the controller to the device.
        ar.ctl_mac, ar.dev_mac = pinfo.dl_src, pinfo.dl_dst
        ar.frame = pinfo.number
        ars[ar.uuid] = ar
        ars_changed(had)
        known = ar
    elseif known and (ar.res_fids or ar.response) then
        known.res_fids = ar.res_fids or known.res_fids
        known.dev_mac = pinfo.dl_src
    else
        return nil
    end
    if not known.subs or not known.iocrs then return nil end
    cls = cls or layout.classify(known.subs)
    if not cls then return nil end
    local up, down = layout.plans_from_ar(known, cls, "Connect in frame " .. known.frame)
    register(up)
    register(down)
    return { kind = "connect", system = cls.system, up = up, down = down }
end

------------------------------------------------------------------------
-- Cyclic frames
------------------------------------------------------------------------
-- The plans of a device recognised by its polled header `h` with the
-- downlink candidate `cand`, in the frame orders found (cand.up_order,
-- cand.down_order; nil: as controllers usually do it).
local function header_plans(w, cand)
    if not cand.up then
        local order = (cand.up_order or cand.down_order) and { up = cand.up_order, down = cand.down_order }
        cand.up, cand.down = layout.mcmb2_plans("polled", w.h.used, w.h.up_mods, cand.mods, cand.dap or w.h.dap,
            w.source, w.dev, order)
        if not cand.up then return nil, nil end
        cand.down.inv = order and layout.inversions(cand.down) or 0
        cand.up.fid, cand.up.sender, cand.up.from_header = w.up_fid, w.dev_mac, true
        cand.down.sender, cand.down.from_header = w.ctl_mac, true
    end
    return cand.up, cand.down
end

-- Whether two plans put every element at the same offsets.
local function same_offsets(a, b)
    local function list(p)
        local t = { p.header.off }
        for _, o in ipairs(p.modules) do t[#t + 1] = o.off end
        for _, o in ipairs(p.dap) do t[#t + 1] = o.off end
        for _, c in ipairs(p.iocs) do t[#t + 1] = c.off end
        return table.concat(t, ",")
    end
    return list(a) == list(b)
end

-- The downlink in another frame order than the usual one: for each
-- candidate, the variant with the downlink's own frame order cut from a
-- frame (layout.polled_down_order; tried on each waiting downlink frame
-- until one is found, HEUR_TRIES frames at most, DOWN_CUT_STEPS steps a
-- frame).
local DOWN_CUT_STEPS = 20000

local function down_variants(w, get, size)
    local budget = { steps = DOWN_CUT_STEPS }
    for _, c in ipairs(w.h.downs) do
        if c.variant == nil and budget.steps > 0 then
            local order = layout.polled_down_order(get, size, w.h, c, budget)
            if order then
                local v = { mods = c.mods, data = c.data, ascii = c.ascii, exact = c.exact, dap = c.dap,
                            up_order = c.up_order, down_order = order }
                local _, usual = header_plans(w, c)
                local _, down = header_plans(w, v)
                -- the usual order after all: nothing new
                c.variant = (down and not (usual and same_offsets(usual, down))) and v or false
            end
        end
    end
end

-- A frame from the controller to a device whose polled header was seen:
-- the downlink candidate that fits it best (layout.best_fit) becomes the
-- layout of both directions (the uplink's IOCS bytes follow the downlink
-- modules). Each candidate comes in the usual frame order and in the one
-- cut from the downlink frames (down_variants). When another candidate fits
-- as well (all data 0 and the IOPS BAD while the controller starts, say),
-- the plan stays open and the following frames of its FrameID are checked
-- again (HEUR_TRIES at most). Returns the downlink plan, or nil if no
-- candidate fits this frame.
local function settle_downlink(w, fid, get, size)
    down_variants(w, get, size)
    local cands, downs, exact = {}, {}, {}
    for _, c in ipairs(w.h.downs) do
        for _, v in ipairs({ c, c.variant or nil }) do
            local _, down = header_plans(w, v)
            if down then
                cands[#cands + 1], downs[#downs + 1], exact[#exact + 1] = v, down, v.exact
            end
        end
    end
    local best, sure = layout.best_fit(downs, get, size, exact)
    if not best then return nil end
    local up, down = header_plans(w, cands[best])
    if up ~= w.up then
        w.up = up
        register(up)
    end
    down.fid = fid
    down.unsettled = (not sure) and w or nil
    register(down)
    return down
end

-- A downlink plan chosen among equals: this frame may tell them apart.
local function resettle(plan, fid, tvb, base, size)
    local w = plan.unsettled
    w.tries = w.tries + 1
    if w.tries > HEUR_TRIES then
        plan.unsettled = nil
        return plan
    end
    local s = tvb:raw(base, size)
    return settle_downlink(w, fid, function(i) return string.byte(s, i + 1) end, size) or plan
end

-- The note on a frame from the controller to a device whose polled header
-- was seen (w) that none of the downlink layouts the header allows fits:
-- the uplink is decoded, so its downlink is not left without a word. When
-- HEUR_TRIES such frames did not fit, the FrameID gets a placeholder plan
-- with this note (first_pass: plan.refused), so later frames say it too.
-- The C front end hands later passes only the FrameIDs it watches: fid
-- is watched.
local function down_note(w, fid)
    watch_carrier(fid)
    noted_fid[fid] = true
    if not w.note then
        local h = w.h
        w.note = { kind = "candidate", settings = { "mcmb2.layouts" }, head = "polled downlink layout not found",
            text = string.format("From the IO controller to the MC-MB2-PN polled base laid out by the %s, but no "
                .. "downlink layout its header allows (Y=%d, Z=%d, %d slot(s) used) fits this frame; to decode it: "
                .. "its layout in mcmb2.layouts", w.source, h.y, h.z, h.used) }
    end
    return w.note
end

-- A cyclic FrameID without a layout (entry: a placeholder of the layout
-- table, or nil): the downlink of a device whose polled header was seen
-- (same two MAC addresses, the other way; the FrameID of the table entry),
-- or a polled uplink header. Bounded: HEUR_TRIES header checks per FrameID,
-- HEUR_TRIES frames per waiting downlink. Returns the plan, or nil and the
-- waiting device whose downlink layouts did not fit this frame (down_note).
-- s: the C-SDU (size bytes) as a string.
local function recognise(fid, s, size, pinfo, entry)
    local function get(i) return string.byte(s, i + 1) end
    local missed
    if #pending_down > 0 then
        local src, dst = pinfo.dl_src, pinfo.dl_dst
        for i, w in ipairs(pending_down) do
            if w.ctl_mac == src and w.dev_mac == dst and (w.down_fid == nil or w.down_fid == fid) then
                local plan = settle_downlink(w, fid, get, size)
                w.tries = w.tries + 1
                if plan or w.tries >= HEUR_TRIES then
                    table.remove(pending_down, i)
                    set_hooks()
                end
                if plan then return plan end
                missed = w
                if w.tries >= HEUR_TRIES and not lookup(by_fid[fid] or {}, src) then
                    register({ fid = fid, sender = src, dir = "down", system = "polled", note = down_note(w, fid),
                               refused = "no downlink layout fits" })
                end
                break
            end
        end
    end
    if entry and entry.dir == "down" then return nil, missed end -- waits for its uplink
    local n = tries[fid] or 0
    if n >= HEUR_TRIES then return nil, missed end
    local h = layout.polled_header(get, size, s)
    if not h then
        tries[fid] = n + 1
        return nil, missed
    end
    local w = { h = h, up_fid = fid, dev_mac = pinfo.dl_src, ctl_mac = pinfo.dl_dst, tries = 0,
                down_fid = entry and entry.out_fid, dev = "hdr" .. pinfo.number,
                source = (entry and "preference, sizes from the polled header in frame " or "polled header in frame ")
                    .. pinfo.number }
    w.up = header_plans(w, h.downs[1])
    register(w.up)
    if not entry or w.down_fid then
        pending_down[#pending_down + 1] = w
        set_hooks()
    end
    return w.up
end

-- A record alike field by field to one of the plan's latest distinct
-- records is replaced by it (records are not changed after the first pass,
-- and a finding makes a table of its own). A healthy base analyses alike
-- frame after frame (nothing to report), and one table per frame was most
-- of the plugins' memory on a long capture and a good part of their time,
-- in the garbage collector (docs/quality.md). The values that differ from
-- frame to frame even on a healthy device (the decoder's per_frame keys:
-- EC-Link's ages of PCI and PCO, MC-MB2-PN's watchdog age, which takes as
-- many values as cycles pass between two watchdog steps) are moved out of
-- the record first, into a packed map by frame number, and put back into
-- it before it is shown.
local RECENT = 8

-- Moves the decoder's per_frame key of rec (frame `n`; the key of the
-- plan's direction, keys.up or keys.down) into per_frame. Frames not of
-- ours are filled with false, so that each chunk stays a Lua array (16
-- bytes a frame) rather than a hash (40 bytes an entry).
local function keep_per_frame(keys, rec, n)
    local k = keys[rec.plan.dir]
    if not k then return end
    for i = per_frame.n + 1, n - 1 do fset(per_frame, i, false) end
    if n > per_frame.n then per_frame.n = n end
    fset(per_frame, n, rec[k] or false)
    rec[k] = nil
end

-- Puts the per_frame value of frame `n` back into its (maybe shared)
-- record, before the record is shown.
local function load_per_frame(keys, rec, n)
    local k = keys[rec.plan.dir]
    if k then rec[k] = fget(per_frame, n) or nil end
end

-- nb: the number of keys of b (counted once, when b was kept). (b may hold
-- a per_frame key put back for a frame that showed it: a's keys are
-- compared, a holds none of those.)
local function alike(a, b, nb)
    local n = 0
    for k, v in pairs(a) do
        if b[k] ~= v then return false end
        n = n + 1
    end
    return n == nb
end

local function keys(t)
    local n = 0
    for _ in pairs(t) do n = n + 1 end
    return n
end

-- A record that shared_record() found alike to a recent one is not kept:
-- it is emptied and made the next frame's record (`spare`). Most frames of
-- a healthy device end so, and a record table (with the hash part its keys
-- grow twice) was most of what a frame allocated.
local function new_record(plan, base, size)
    local rec = spare
    spare = nil
    return record.new(plan, base, size, rec)
end

-- A record nothing else holds (a decoder hands its record on only with a
-- finding, such as a command's, and such a record is kept): emptied, it is
-- the next frame's (new_record).
local function release(rec)
    for k in next, rec do rec[k] = nil end
    spare = rec
end

local function shared_record(rec, n)
    if once then return rec end
    local per = systems.decoder(rec.plan.system).per_frame
    if per then keep_per_frame(per, rec, n) end
    if rec.findings ~= record.NO_FINDINGS then return rec end
    local recent = last_rec[rec.plan]
    if not recent then
        recent = { next = 1, n = {} }
        last_rec[rec.plan] = recent
    end
    local counts = recent.n
    for i = 1, #recent do
        local r = recent[i]
        if alike(rec, r, counts[i]) then
            release(rec)
            return r
        end
    end
    recent[recent.next] = rec
    counts[recent.next] = keys(rec)
    recent.next = recent.next % RECENT + 1
    return rec
end

-- The record of one cyclic frame of a known plan (C-SDU as string s).
-- cut (a frame the capture cut, snaplen): { size = the C-SDU's bytes on
-- the wire, cap = the frame's bytes captured, wire = on the wire }; s then
-- holds the C-SDU bytes captured, rec.cut their number, and the decoder
-- reads only those (pnio_record.luam).
local function analysed(plan, s, t, frame, cut)
    local dec = systems.decoder(plan.system)
    if not dec then return nil end
    local size = cut and cut.size or #s
    local rec = new_record(plan, 2, size)
    -- (a short frame the capture cut is shown from the bytes captured too)
    if cut then
        rec.cut = #s
        record.add_finding(rec, "top", dec.cut, string.format(
            "Cut by the capture at %d of its %d bytes (snaplen): %s; only the bytes captured are decoded, "
            .. "the counters from what survived", cut.cap, cut.wire, #s >= size
            and "the C-SDU is whole, the APDU status is not in the capture"
            or string.format("C-SDU bytes %d..%d of %d are not in the capture", #s, size - 1, size)))
    end
    if size < plan.need then
        record.add_finding(rec, "top", dec.short, string.format(
            "C-SDU has %d bytes, the layout needs %d", size, plan.need))
        health.pnio(rec, t, frame)
        return rec
    end
    dec.analyse(rec, s, t, frame)
    health.pnio(rec, t, frame)
    return rec
end

-- A frame of the stream of `plan` (vrshark/pnio_stops.luam), first pass:
-- cc its cycle counter, nil when not known.
local function watch(plan, t, n, cc)
    local dec = systems.decoder(plan.system)
    if dec and dec.stops then dec.stops:seen(plan, t, n, cc) end
end

local inferred -- (below)

-- A finding at the top of the record, before the decoder's (the order the
-- full tree shows them in: "top" first, and the sparse display's).
local function first_finding(rec, ex, text)
    record.add_finding(rec, "top", ex, text)
    table.insert(rec.findings, 1, table.remove(rec.findings))
end

-- The plans (up, down) of a layout settled by vrshark.pnio_infer.
local function inferred_plans(res, dev)
    local source = string.format("inferred from cyclic frames %d..%d", res.first, res.last)
    if res.system == "eclink" then
        return layout.eclink_plans(res.outlen, res.dap, source, dev, res.order)
    end
    return layout.mcmb2_plans("duplex", 1, res.up_mods, res.down_mods, res.dap, source, dev, res.order, res.ascii)
end

-- A layout settled by vrshark.pnio_infer: both plans registered, and every
-- frame of the run (this one last) analysed in frame order. A layout
-- settled again after a contradiction (reopen()): the frame that re-opened
-- it carries the note, and the plans of the layout it replaces lead to
-- these (plan.next: frames decoded by them are decoded again, on a later
-- pass, by a copy of these, redone()).
local function settle(res)
    local up, down = inferred_plans(res, "inferred" .. res.last)
    reopening[res.up.fid], reopening[res.down.fid] = nil, nil
    local again = res.reopened
    local list = {}
    for _, pr in ipairs({ { up, res.up }, { down, res.down } }) do
        local plan, run = pr[1], pr[2]
        if plan then
            plan.fid, plan.sender, plan.entry, plan.inferred = run.fid, addr_of[run.src], res.entry, res
            plan.order_note, plan.alt_entry = res.order_note, res.alt_entry
            register(plan)
            for _, f in ipairs(run.frames) do list[#list + 1] = { f[1], f[2], f[3], plan, #list + 1 } end
            for _, old in ipairs(again and again.plans or {}) do
                if old.dir == plan.dir then old.next = plan end
            end
            plan.again = again and true
        end
        run.frames = nil
    end
    -- (by frame number; numbers repeat only on the first pass of tshark -2
    -- -R, vrshark/passes.luam: there the last frame with a number is the one
    -- kept, so its record is written last: frames of a number by time, then
    -- as fed)
    table.sort(list, function(a, b)
        if a[1] ~= b[1] then return a[1] < b[1] end
        if a[3] ~= b[3] then return a[3] < b[3] end
        return a[5] < b[5]
    end)
    for _, f in ipairs(list) do
        local rec = analysed(f[4], f[2], f[3], f[1])
        if rec then watch(f[4], f[3], f[1], nil) end
        local dec = systems.decoder(f[4].system)
        if rec and again and f[1] == again.frame then first_finding(rec, dec.reopened, again.text) end
        if rec and f[1] == res.last then
            record.add_finding(rec, "top", dec.inferred, string.format(
                "Cyclic data layout inferred from frames %d..%d (%s%s); to pin it, "
                .. "add to mcmb2.layouts: %s%s", res.first, res.last, cut_connect
                and string.format("no Connect read: the capture cut the PNIO-CM datagram in frame %d", cut_connect)
                or "no Connect in the capture", again and string.format(", re-opened in frame %d", again.frame)
                or "", res.entry, res.alt_entry and string.format("; or, text as ASCII (against the frame order): %s",
                res.alt_entry) or ""))
        end
        fset(frames, f[1], rec and shared_record(rec, f[1]))
    end
end

-- Evidence against a layout inferred from the cyclic frames, in a frame it
-- decoded (rec): the decoder's (rec.contradicts: a watchdog that went back,
-- a base unit number that moved) or an IOxS byte neither GOOD (0x80) nor
-- BAD (0x00, 0x20, 0x40, 0x60). Only asked when the decoder set one of
-- rec.contradicts, rec.ioxs_bad: the settled path costs a field test.
local IOXS_LEGAL = { [0x80] = true, [0x00] = true, [0x20] = true, [0x40] = true, [0x60] = true }
local function contradiction(rec, s)
    if rec.contradicts then return rec.contradicts end
    for _, x in ipairs(record.ioxs_list(rec.plan)) do
        local v = string.byte(s, x.off + 1)
        if v and not IOXS_LEGAL[v] then
            return string.format("%s of slot %d/0x%x is 0x%02x, neither GOOD nor BAD",
                x.iocs and "IOCS" or "IOPS", x.slot, x.subslot, v)
        end
    end
    return nil
end

local function unregister(plan)
    -- (its frames are no longer decoded: its stream is not watched either)
    stops.forget(plan)
    local t = by_fid[plan.fid] or {}
    for i = #t, 1, -1 do
        if t[i] == plan then table.remove(t, i) end
    end
end

-- Re-openings of the layouts of one FrameID pair at most (a sender that
-- restarts again and again is not inferred again each time).
local MAX_REOPEN = 4

-- A layout inferred from the cyclic frames that frame n contradicts (why):
-- its plans are taken out, vrshark.pnio_infer starts both runs again from
-- this frame (the contradicted layout ranked below any other) and this
-- frame carries the note, until the runs settle again (settle()).
local function reopen(plan, why, rec_header, fid, s, pinfo, n)
    local res = plan.inferred
    local count = (res.reopened and res.reopened.count or 0) + 1
    if count > MAX_REOPEN then
        plan.inferred = nil
        return nil
    end
    local plans = {}
    for _, p in ipairs(by_fid[res.up.fid] or {}) do if p.inferred == res then plans[#plans + 1] = p end end
    for _, p in ipairs(by_fid[res.down.fid] or {}) do if p.inferred == res then plans[#plans + 1] = p end end
    for _, p in ipairs(plans) do unregister(p) end
    local text = string.format("Layout inferred from frames %d..%d contradicted in frame %d: %s; inference "
        .. "re-opened (was %s)", res.first, res.last, n, why, res.entry)
    local hdr = plan.header or plan.image
    infer.reopen(runs, res, { frame = n, text = text, entry = res.entry, plans = plans, count = count,
                              fids = { res.up.fid, res.down.fid } },
        rec_header and hdr and { fid = plan.fid, off = hdr.off })
    set_hooks()
    -- (was: on a later pass the frame is decoded by the layout settled again, redone())
    local note = { kind = "candidate", head = "layout re-opened", settings = {}, text = text, reopened = true,
                   was = plan }
    -- the frames of both FrameIDs until it settles again (inferred()): not
    -- decoded in one pass, and not in silence; -2 decodes them (settle());
    -- early: a hint known at the end of the capture replaces it
    local wait = { kind = "candidate", head = "layout re-opened, not settled again yet", settings = {}, early = true,
                   text = string.format("Not decoded: the layout of this FrameID was re-opened in frame %d and is "
                       .. "not settled again yet (tshark -2 or the packet list after loading decodes it with the "
                       .. "layout that fits the whole run; mcmb2.layouts pins one)", n) }
    reopening[res.up.fid], reopening[res.down.fid] = wait, wait
    -- (evidence against a header: this frame is the new runs' first; an
    -- IOxS byte neither GOOD nor BAD: the next one, this frame cuts no layout)
    if not rec_header then return note end
    local got = inferred(fid, s, pinfo, n)
    if got and got.kind ~= "candidate" then return got end
    return note
end

-- The runs of a layout re-opened (reopen()) given up, no layout fitting
-- any more (vrshark/pnio_infer.luam: hint h, h.reopened the info of
-- reopen()): rec, the note of candidate(), replaces the note that it is
-- not settled again yet (reopening[]) on both FrameIDs, so the frames
-- the capture cut carry it too. Once per hint, when rec is made.
local function given_up_again(h, rec)
    for _, f in ipairs(h.reopened.fids) do reopening[f] = rec end
end

-- A frame decoded on the first pass by a layout that was contradicted and
-- replaced later (plan.next, settle()), or by the layout that replaced it
-- (plan.again): decoded again, on the later pass, by a copy of the layout
-- that replaced it, with its own state (the frames come in frame order in
-- tshark -2: the watchdog ages run on across the contradiction). The
-- record keeps the notes of the inference (re-opened; inferred, but not
-- that of the layout contradicted).
local function redone(rec0, plan, tvb, pinfo, n)
    local superseded = plan.next ~= nil
    while plan.next do plan = plan.next end
    if not plan.redo then
        local up, down = inferred_plans(plan.inferred, "redo" .. plan.inferred.last)
        plan.redo = (plan.dir == "up") and up or down
        plan.redo.fid, plan.redo.sender, plan.redo.entry = plan.fid, plan.sender, plan.entry
    end
    local len = tvb_len(tvb)
    if tvb_reported_len(tvb) > len or len - 6 <= 0 then return fget(frames, n) end
    local rec = analysed(plan.redo, tvb_raw(tvb, 2, len - 6), p_abs_ts(pinfo), n)
    local dec = systems.decoder(plan.system)
    if rec and rec0.was then first_finding(rec, dec.reopened, rec0.text) end
    if rec and rec0.findings and rec0.findings ~= record.NO_FINDINGS then
        for _, f in ipairs(rec0.findings) do
            if f.ex == dec.reopened or (f.ex == dec.inferred and not superseded) then
                record.add_finding(rec, f.anchor, f.ex, f.text)
            end
        end
    end
    rec = rec and shared_record(rec, n)
    fset(frames, n, rec)
    return rec
end

local SYSTEM_NAME = { duplex = "an MC-MB2-PN duplex/simplex base", polled = "an MC-MB2-PN polled base",
                      eclink = "an EC-Link BU" }

-- The record of the frames of a run that looked like ours but has not
-- settled (vrshark/pnio_infer.luam hint()): the candidate note with the
-- layout-table entries that decode it. The first time a hint is seen,
-- every earlier frame of its runs gets it too (shown on the second pass);
-- a run that settles later replaces them (settle()). A layout re-opened
-- (reopen()) whose runs were given up, no layout fitting any more
-- (h.reopened, the info of reopen()): the note names the re-opening frame
-- and the entry of the layout it had, on every frame of both FrameIDs
-- from then on (given_up_again(): the frames the capture cut too), and on
-- the second pass on those since the re-opening frame. Only builds the
-- record (kept per hint: hint_recs).
local function candidate(h, frame)
    local rec = hint_recs[h]
    if not rec then
        local settings = {}
        for i, e in ipairs(h.entries) do settings[i] = "mcmb2.layouts:" .. e end
        local again = h.reopened
        if again then
            rec = { kind = "candidate", settings = settings, head = "layout re-opened, not inferred again",
                    -- (short: an expert text is cut at 240 bytes; the entry last, whole in the setting)
                    text = string.format("Not decoded: layout re-opened in frame %d, not inferred again (%s); a "
                        .. "Connect in the capture or mcmb2.layouts decides it (it was %s)", again.frame, h.why,
                        table.concat(settings, " or ")) }
        elseif h.short then
            -- (an excerpt too short for the evidence: the frame count, about how many it takes)
            rec = { kind = "candidate", settings = settings, text = string.format(
                "Shaped like %s, %s; to decode them: %s", SYSTEM_NAME[h.system], h.why,
                table.concat(settings, " or ")) }
        else
            rec = { kind = "candidate", settings = settings, early = h.early, text = string.format(
                "Looks like %s, but its layout was not inferred (%s); to decode it now: %s",
                SYSTEM_NAME[h.system], h.why, table.concat(settings, " or ")) }
        end
        hint_recs[h] = rec
        for _, list in ipairs(h.lists or {}) do
            for _, f in ipairs(list) do
                local was = fget(frames, f[1])
                if f[1] ~= frame and not (was and was.reopened) then fset(frames, f[1], rec) end
            end
        end
        h.lists = nil
    end
    if frame == h.frame and h.ambiguous then
        return { kind = "candidate", settings = rec.settings, text = rec.text, ambiguous = h.ambiguous }
    end
    return rec
end

-- On the second pass, a frame of a run that was not settled by the end of
-- the capture but looked like ours (pnio_infer.final_hint): the candidate
-- note. `unsettled` (whether any run is left so) is asked once, on the
-- first frame of the second pass; nil: not asked yet.
local function final_candidate(tvb, pinfo)
    if unsettled == nil then unsettled = infer.unsettled(runs) end
    if not unsettled then return nil end
    local fid = tvb:range(0, 2):uint()
    if fid < 0x8000 or fid > 0xFBFF then return nil end
    local h = infer.final_hint(runs, fid, tostring(pinfo.dl_src), tostring(pinfo.dl_dst))
    return h and candidate(h, pinfo.number)
end

-- A cyclic frame of no known layout (its C-SDU the string s), fed to
-- vrshark.pnio_infer; n: the frame number. (A run given up without a hint
-- takes nothing more: asked first, before the frame's time is made.)
function inferred(fid, s, pinfo, n)
    local addr = p_dl_src(pinfo)
    local src, dst = tostring(addr), tostring(p_dl_dst(pinfo))
    if infer.given_up(runs, fid, src, dst) then return nil end
    if not addr_of[src] then addr_of[src] = addr end
    local was = infer.alive(runs)
    local res = infer.feed(runs, fid, src, dst, s, p_abs_ts(pinfo), n)
    if infer.alive(runs) ~= was then set_hooks() end
    if #runs.watch > 0 then
        -- the C front end hands later passes only the FrameIDs it watches
        for _, f in ipairs(runs.watch) do watch_carrier(f) end
        runs.watch = {}
    end
    if #runs.unwatch > 0 then
        -- (a FrameID watched only for an excerpt too short, whose runs grew
        -- past it: not watched any more, unless a layout or a note has it)
        for _, f in ipairs(runs.unwatch) do
            if not by_fid[f] and not noted_fid[f] then front.unwatch(f) end
        end
        runs.unwatch = {}
    end
    if not res then return reopening[fid] end
    if res.kind == "candidate" then
        local fresh = not hint_recs[res]
        local rec = candidate(res, n)
        if fresh and res.reopened then given_up_again(res, hint_recs[res]) end
        return rec
    end
    settle(res)
    return fget(frames, n)
end

-- The frames of a direction whose Connect could not be learned
-- (pnio_layout.plans_from_ar): one note for all, naming the setting that
-- decodes them.
local function refused_note(plan)
    if not plan.note then
        plan.note = { kind = "candidate", settings = { "mcmb2.layouts" }, head = "not decoded, layout not learned",
            text = string.format("Not decoded: the Connect of %s does not describe this %s (%s); "
                .. "to decode it: its layout in mcmb2.layouts", SYSTEM_NAME[plan.system] or SYSTEM_NAME.duplex,
                (plan.dir == "up") and "uplink" or "downlink", plan.refused) }
    end
    return plan.note
end

-- A frame of ours the capture cut before its layout was known (a polled
-- base waiting for its header, a FrameID whose layout was inferred only
-- later): not decoded, since a cut frame never decides a layout, and said
-- so. when: "known" or "inferred (frames a..b)"; entry: the layout-table
-- entry that decodes it, where one is known.
local function cut_note(plan, cut, when, entry)
    return { kind = "candidate", head = "cut by the capture, layout not known", settings = entry
                 and { "mcmb2.layouts:" .. entry } or {},
             text = string.format("Not decoded: cut by the capture at %d of %d bytes before the layout of this %s "
                 .. "was %s%s", cut.cap, cut.wire, (plan.dir == "up") and "uplink" or "downlink", when,
                 entry and ("; to decode it: mcmb2.layouts:" .. entry) or "") }
end

-- On a later pass, a frame the capture cut (no record from the first
-- pass) of a FrameID and sender whose layout was inferred from the cyclic
-- frames after it: the note, with the entry that decodes it.
local function cut_before_inferred(tvb, pinfo)
    local cands = by_fid[tvb:range(0, 2):uint()]
    local plan = cands and lookup(cands, p_dl_src(pinfo))
    local res = plan and plan.inferred
    if not res then return nil end
    return cut_note(plan, { cap = pinfo.caplen, wire = pinfo.len }, string.format("inferred (frames %d..%d)",
        res.first, res.last), plan.entry)
end

-- tvb: the PN-RT frame from the FrameID on, len bytes captured; n: the
-- frame number; thrown: PN-RT raised an exception on it (a frame the
-- capture cut is one: its C-SDU size comes from the reported length, the
-- last 4 bytes captured are no APDU status).
local function first_pass(fid, tvb, pinfo, len, n, thrown)
    local cands = by_fid[fid]
    local base = 2
    local size = len - base - 4
    local cut
    if thrown then
        local rl = tvb:reported_len()
        if rl > len then
            size = rl - base - 4
            cut = { size = size, cap = pinfo.caplen, wire = pinfo.len }
        end
    end
    if size <= 0 then return nil end
    local plan = cands and lookup(cands, p_dl_src(pinfo))
    -- (a cut frame is decoded by a layout known, never used to find one)
    if cut and (not plan or plan.unsettled or plan.deferred or plan.refused) then
        if plan and plan.refused then return refused_note(plan) end
        if plan then return cut_note(plan, cut, "known") end
        return reopening[fid]
    end
    local missed
    if plan and plan.unsettled then
        plan = resettle(plan, fid, tvb, base, size)
    elseif plan and plan.deferred then
        plan, missed = recognise(fid, tvb_raw(tvb, base, size), size, pinfo, plan)
    elseif not plan then
        if not heuristic or fid < 0x8000 or fid > 0xFBFF then return nil end
        local s = tvb_raw(tvb, base, size)
        plan, missed = recognise(fid, s, size, pinfo, nil)
        if not plan then return inferred(fid, s, pinfo, n) or (missed and down_note(missed, fid)) end
    end
    if not plan then return missed and down_note(missed, fid) end
    if plan.refused then return refused_note(plan) end
    local s = tvb_raw(tvb, base, cut and math.min(len - base, size) or size)
    local t = p_abs_ts(pinfo)
    local rec = analysed(plan, s, t, n, cut)
    -- (the stream's deadlines and cycle; the cycle counter after the C-SDU)
    if rec then
        local cc
        if not cut then
            local hi, lo = string.byte(tvb_raw(tvb, len - 4, 2), 1, 2)
            cc = hi * 256 + lo
        end
        watch(plan, t, n, cc)
    end
    -- (a layout inferred from the cyclic frames: evidence against it re-opens it)
    if rec and plan.inferred and (rec.contradicts or rec.ioxs_bad) and not cut then
        local why = contradiction(rec, s)
        if why then
            local got = reopen(plan, why, rec.contradicts ~= nil, fid, s, pinfo, n)
            if got then return got end
        end
    end
    -- (fresh: nobody else holds rec in a one-pass run)
    if once then return rec, true end
    return rec and shared_record(rec, n)
end

local function show(rec, tvb, pinfo, tree)
    if rec.kind == "candidate" then
        systems.decoder("duplex").show_candidate(rec, tvb, tree)
        return
    end
    if rec.kind ~= "connect" then
        return systems.decoder(rec.plan.system).show(rec, tvb, pinfo, tree)
    end
    local function fid(plan)
        if not plan or not plan.fid then return "none" end
        -- a direction left out is said, with the object that made it so
        local refused = plan.refused and (" not learned (" .. plan.refused .. ")") or ""
        if plan.fid == 0xFFFF then return "assigned in the response" .. refused end
        return string.format("0x%04x", plan.fid) .. refused
    end
    local text = string.format("%s device: uplink FrameID %s, downlink FrameID %s", rec.system, fid(rec.up),
        fid(rec.down))
    systems.decoder(rec.system).show_connect(rec, tvb, tree, text)
end

-- A frame of ours that Wireshark's PN-RT or PNIO reported as malformed
-- (the exception is in the tree): when the layout fits the frame, the
-- decode stands and this note says why both are there. Wireshark 4.6 reads
-- an RT_CLASS_1 frame (FrameID 0x8000-0xBFFF) as secured when C-SDU bytes
-- 6-7 hold the C-SDU length less 20 (PN-RT) or less 4 (PNIO), and PNIO,
-- knowing the IOCR from the Connect, then runs out of bytes: any data byte
-- pair of a device can do that.
local function pn_malformed_note(rec, tvb, root)
    local plan, size = rec.plan, rec.size
    if not plan or size < plan.need then return end -- the decoder's "short" finding says it
    local who = "PROFINET dissector"
    if size >= 8 then
        local v = tvb:range(rec.base + 6, 2):uint()
        if v == size - 20 or v == size - 4 then
            who = string.format("%s (C-SDU bytes 6-7, %d, read as a SecurityLength)", v == size - 20 and "PN-RT"
                or "PNIO", v)
        end
    end
    root:add_proto_expert_info(systems.decoder(plan.system).pn_malformed, string.format(
        "Malformed to Wireshark's %s, but the layout (%s) fits its %d-byte C-SDU: decoded", who, plan.source,
        size))
end

-- The decoder whose findings a record of a cyclic frame or a Connect holds
-- (a candidate's note is mcmb2's).
local function owner(rec)
    return systems.decoder(rec.plan and rec.plan.system or rec.system or "duplex")
end

-- The tree and columns of a cyclic frame's record: in full (view nil), or
-- the decoder's sparse() when it can (view: vrshark/frontends.luam).
local function display(rec, tvb, pinfo, tree, view, thrown)
    if not view then
        local root = show(rec, tvb, pinfo, tree)
        -- (a frame the capture cut: its own note says why PN-RT threw)
        if thrown and root and not rec.cut then pn_malformed_note(rec, tvb, root) end
        return
    end
    local dec = rec.plan and systems.decoder(rec.plan.system)
    if not (dec and dec.sparse and dec.sparse(rec, tvb, pinfo, tree, view)) then
        show(rec, tvb, pinfo, tree)
    end
end

-- Whether the run of this frame (FrameID fid, its Ethernet addresses) was
-- given up without a hint (infer.given_up()): it never comes back until the
-- next file, so its two Addresses are kept and compared with the frame's
-- (a foreign device's frames, every one of them: no station texts made, no
-- key built; infer.given_up() is asked once per run).
local function gave_up(fid, pinfo)
    local src, dst = p_dl_src(pinfo), p_dl_dst(pinfo)
    local list = gone[fid]
    if list then
        for i = 1, #list, 2 do
            if list[i] == src and list[i + 1] == dst then return true end
        end
    end
    if not infer.given_up(runs, fid, tostring(src), tostring(dst)) then return false end
    if not list then
        list = {}
        gone[fid] = list
    end
    list[#list + 1], list[#list + 2] = src, dst
    return true
end

-- On a later pass, a frame whose first-pass record may not stand: asked
-- only when it has none, when it holds a one-pass early hint, or when the
-- layout that decoded it was contradicted since.
local function revised(rec, tvb, pinfo, n)
    -- (decoded by a layout contradicted later: decoded again by the one that replaced it)
    local p = rec and (rec.plan or rec.was)
    if p and (p.next or p.again) then rec = redone(rec, p, tvb, pinfo, n) end
    -- (a one-pass early hint gives way to the hint known at the end)
    if (rec == nil or rec.early) and unsettled ~= false and tvb:len() >= 2 then
        rec = final_candidate(tvb, pinfo) or rec
    end
    -- (a frame the capture cut before the layout of its run was inferred)
    if rec == nil and tvb_reported_len(tvb) > tvb_len(tvb) then rec = cut_before_inferred(tvb, pinfo) end
    return rec
end

-- The display of frame n's record (fresh: made by this first pass, held
-- by nobody else; visited: pinfo.visited): its per-frame value put back,
-- the tree and columns as the view says (none in a quiet one), then a
-- fresh record without findings is the next frame's table.
local function shown(rec, fresh, n, visited, tvb, pinfo, tree, view, thrown, as)
    local plan = rec.plan
    -- (the decoder whose findings the record holds, as owner() says)
    local dec = systems.decoder(plan and plan.system or rec.system or "duplex")
    local per = not once and plan and dec.per_frame
    if per then load_per_frame(per, rec, n) end
    if not (view and view.quiet) then
        -- (MC-MB2-PN and EC-Link frames: the view over the Protos of their
        -- fields, front.view_for(): the C front end's, or made in Lua)
        local protos = not thrown and plan and (dec.lua_protos or dec.proto == mcmb2_proto and dec.proto)
        if protos then view = view_for(protos, tree, visited, view) end
        -- (under the decoder's own Proto: pnio_systems.through() says why;
        -- as: the frame is dissected under it already)
        if dec.proto == (as or carrier) then
            display(rec, tvb, pinfo, tree, view, thrown)
        else
            systems.through(dec, display, rec, tvb, pinfo, tree, view, thrown)
        end
    end
    if fresh and rec.findings == record.NO_FINDINGS then release(rec) end
end

-- A PN-RT frame after PN-RT (the transport's entry: PN-RT ran on it, or,
-- for a frame of ours the capture cut, did not): its record, from the
-- first pass or kept for a later one, and its display. view: what is
-- looked at (vrshark/seam.luam view(): nil everything, quiet nothing, or
-- sparse: the decoder's sparse() adds only that, or says it needs show());
-- thrown: PN-RT (or PNIO below it) raised an exception on this frame; len:
-- the frame's length, or nil; as: the decoder's Proto the C front end
-- handed the frame to (register(): entry_proto()), nil for the carrier's.
-- Returns the record, or nil for a frame not of ours. (Every frame of a foreign device in the Lua-only mode comes
-- here: the first pass costs it the FrameID read and a table lookup.)
local function cyclic(tvb, pinfo, tree, view, thrown, len, as)
    -- (the note is an expert item: everything is shown)
    if thrown then view = nil end
    local visited = p_visited(pinfo)
    local rec, fresh, n
    if visited then
        n = p_number(pinfo)
        rec = fget(frames, n)
        local p = rec and (rec.plan or rec.was)
        if not rec or rec.early or (p and (p.next or p.again)) then rec = revised(rec, tvb, pinfo, n) end
    else
        len = len or tvb_len(tvb)
        -- (the FrameID from the bytes: a TvbRange costs more than the frame's other reads)
        local b1, b2 = string.byte(len >= 2 and tvb_raw(tvb, 0, 2) or "", 1, 2)
        local fid = b1 and (b1 * 256 + b2)
        if fid and (by_fid[fid] or (fid >= 0x8000 and fid <= 0xFBFF and heuristic
                    and ((tries[fid] or 0) < HEUR_TRIES or #pending_down > 0
                         or not gave_up(fid, pinfo)))) then
            n = p_number(pinfo)
            rec, fresh = first_pass(fid, tvb, pinfo, len, n, thrown)
            if not once then fset(frames, n, rec) end
        end
    end
    if rec then shown(rec, fresh, n, visited, tvb, pinfo, tree, view, thrown, as) end
    return rec
end

-- Which frames are of ours, for the transport's rules on the frames PN-RT
-- must not see or reported malformed: frame n's record, FrameID fid's
-- layouts (or nil).
local function recorded(n) return fget(frames, n) end
local function has_fid(fid) return by_fid[fid] end

------------------------------------------------------------------------
-- The Connect
------------------------------------------------------------------------
-- A PNIO-CM datagram (UDP 34964 or a controller's port) reaches the
-- carrier through its transport, which calls cut_datagram() for one the
-- capture cut and connect() for the others, after the UDP heuristics
-- (DCE/RPC) have run.
-- A DCE/RPC datagram the capture cut (snaplen): when it may be a Connect
-- (a request or response whose operation is 0, or was cut before it), the
-- note that its layout cannot be read and what decodes its cyclic frames
-- instead; cut_connect keeps its frame for the notes of those frames.
-- Returns 0: the datagram is left to DCE/RPC, which reports the cut.
local function cut_datagram(tvb, pinfo, tree)
    local rec
    if pinfo.visited then
        rec = fget(frames, pinfo.number)
    elseif learn then
        local cap = tvb:len()
        local ptype = cap >= 2 and tvb:range(1, 1):uint()
        local opnum
        if cap >= 70 then
            -- (the byte order of the DCE/RPC header: its data representation, byte 4)
            local r = tvb:range(68, 2)
            opnum = bit.band(tvb:range(4, 1):uint(), 0x10) ~= 0 and r:le_uint() or r:uint()
        end
        if (ptype == 0 or ptype == 2) and (opnum == nil or opnum == 0) then
            local what = (opnum and "Connect " or "PNIO-CM ") .. (ptype == 0 and "request" or "response")
            rec = { kind = "cut_connect", text = string.format("%s cut by the capture at %d of %d bytes "
                .. "(snaplen)%s: its layout cannot be read; the cyclic frames are decoded by the layout inferred "
                .. "from them, or by their mcmb2.layouts entry", what, pinfo.caplen, pinfo.len,
                opnum and "" or ", before its operation number") }
            cut_connect = cut_connect or pinfo.number
            fset(frames, pinfo.number, rec)
        end
    end
    if rec then systems.decoder("duplex").show_cut_connect(rec, tvb, tree) end
    return 0
end

-- A DCE/RPC datagram after DCE/RPC: the Connect blocks read on the first
-- pass, its note shown. Returns the record (nil: no Connect of ours) and
-- whether it is a request of devices of no system of ours (the C front end
-- then hands over no more requests with these expected submodules while
-- no AR is held: nothing would be read).
local function connect(tvb, pinfo, tree)
    local rec
    if pinfo.visited then
        rec = fget(frames, pinfo.number)
    elseif learn then
        local s = defragment(tvb:raw(0, tvb:len()))
        local blocks, request
        if s then blocks, request = connect_blocks(s) end
        if blocks then
            -- (the response comes from the device's own port to the request's)
            if request then front.request_from(pinfo) end
            rec = learn_connect(pinfo, blocks)
            fset(frames, pinfo.number, rec)
            if request and not rec and blocks.key and not_ours[blocks.key] then return nil, true end
        end
    end
    if rec then
        local dec = owner(rec)
        if dec.proto == carrier then show(rec, tvb, pinfo, tree)
        else systems.through(dec, show, rec, tvb, pinfo, tree) end
    end
    return rec, false
end

-- The transport takes the frames, and the hooks are set as the preferences
-- are at load (the C front ends ask them before the first file starts).
front.serve({ cyclic = cyclic, cut_datagram = cut_datagram, connect = connect, recorded = recorded,
              has_fid = has_fid })
do
    local prefs = systems.prefs()
    heuristic, learn = prefs.heuristic, prefs.connect
end
set_hooks()
