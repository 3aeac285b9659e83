-- vrshark.eclink_handshake: the EC-Link image handshake rules, one
-- implementation for every transport (Modbus/TCP, PROFINET IO).
--
--   PCI (input image byte 0) must move at least every 500 ms.
--   A new CCI (input byte 1) is a command from the RU; CAO (output byte 3)
--   must echo it within 2000 ms.
--   A new CCO (output byte 1) is a command to the RU; CAI (input byte 3)
--   must echo it within 2000 ms.
--   PCO (output image byte 0) must move at least every 2000 ms.
--   A change of the BU state (input byte 20) is reported.
--
-- Usage, on the first pass in frame order, one state per conversation:
--   local st = eh.new()
--   local r = eh.update(st, inp, out, t, frame, ref)
-- inp = { pci =, cci =, cai =, bu = } the input image values this frame
-- carries (nil, or any member nil, when it does not), out = { pco =, cco =,
-- cao = } likewise for the output image, t the frame time in seconds, ref
-- anything the caller wants handed back when a later frame answers a command
-- of this frame (its per-frame record). The result:
--   r.findings   list of { key, text }; key indexes the table built by
--                eh.experts() (the same wording on every transport)
--   r.pci_age, r.pco_age   seconds since the counter last moved (frames that
--                carry it)
--   r.bu_state_prev   the BU state before this frame, where it changed
--   r.links      on an echo frame: cmd_from_ru_in / cmd_to_ru_in (frame of
--                the command) and cmd_from_ru_latency / cmd_to_ru_latency
--   r.back       list of { ref, name, frame }: forward links for earlier
--                frames (cao_in / cai_in = this frame)
-- A stall is reported on the first frame that carries the unchanged counter
-- after the limit; a missing echo on the first frame of the conversation
-- after the deadline, and an echo that comes after the deadline again on the
-- frame that carries it (with its latency). All of it is known when the frame
-- is first seen, so one pass and two passes agree.
--
-- The module keeps nothing itself and has no side effects at load time;
-- experts() creates ProtoExpert objects only when a plugin calls it. Its
-- own dependencies are required on first use: Wireshark also runs this file
-- on its own at start-up, before any plugin has set package.path.
local handshake, image

local M = {}

local function deps()
    if not handshake then
        handshake = require("vrshark.handshake")
        image = require("vrshark.eclink_image")
    end
end

M.LIMITS = { pci = 0.5, pco = 2.0, cmd = 2.0 }

-- key, name suffix, summary, severity
local EXPERTS = {
    { "pci_stalled", "pci_stalled", "PCI stalled over 500 ms", "WARN" },
    { "pco_stalled", "pco_stalled", "PCO stalled over 2000 ms", "WARN" },
    { "cmd_from_ru", "cmd_from_ru", "New command from RU (CCI)", "CHAT" },
    { "cmd_from_ru_ack", "cmd_from_ru.ack", "Command from RU acknowledged by CAO", "CHAT" },
    { "cmd_from_ru_late", "cmd_from_ru.late", "Command from RU not acknowledged by CAO within 2000 ms", "WARN" },
    { "cmd_to_ru", "cmd_to_ru", "New command to RU (CCO)", "CHAT" },
    { "cmd_to_ru_ack", "cmd_to_ru.ack", "Command to RU acknowledged by CAI", "CHAT" },
    { "cmd_to_ru_late", "cmd_to_ru.late", "Command to RU not acknowledged by CAI within 2000 ms", "WARN" },
    { "bu_state_change", "bu_state_change", "BU state changed", "NOTE" },
}

-- The handshake expert fields of one transport's protocol, named
-- <prefix>.pci_stalled etc. Returns a table key -> ProtoExpert and the list
-- in registration order (to append to the protocol's experts).
function M.experts(prefix)
    local by_key, list = {}, {}
    for _, e in ipairs(EXPERTS) do
        local ex = ProtoExpert.new(prefix .. "." .. e[2], e[3], expert.group.SEQUENCE, expert.severity[e[4]])
        by_key[e[1]] = ex
        list[#list + 1] = ex
    end
    return by_key, list
end

function M.new()
    deps()
    return { pci = {}, pco = {}, from_ru = {}, to_ru = {} }
end

local function bu_name(v)
    return image.vs.bu_state[v] or string.format("0x%02x", v)
end

-- One direction of commands: the findings and links of handshake.echo().
-- d: { key, what, req, ans, link, back }
local function commands(r, list, d, frame)
    for _, e in ipairs(list) do
        if e.kind == "new" then
            r.findings[#r.findings + 1] = { d.key, string.format("New command %s: %s %d -> %d", d.what, d.req,
                e.old, e.value) }
        elseif e.kind == "late" then
            r.findings[#r.findings + 1] = { d.key .. "_late", string.format(
                "Command %s (%s %d, frame %d) not acknowledged by %s within 2000 ms", d.what, d.req, e.value,
                e.since, d.ans) }
        else
            r.links[d.link .. "_in"] = e.since
            r.links[d.link .. "_latency"] = e.delay
            r.back[#r.back + 1] = { e.ref, d.back, frame }
            if e.kind == "acked_late" then
                r.findings[#r.findings + 1] = { d.key .. "_late", string.format(
                    "%s echoed %s %d after %.0f ms (limit 2000 ms)", d.ans, d.req, e.value, e.delay * 1000) }
            else
                r.findings[#r.findings + 1] = { d.key .. "_ack", string.format(
                    "%s %d acknowledges the command %s of frame %d after %.0f ms", d.ans, e.value, d.what,
                    e.since, e.delay * 1000) }
            end
        end
    end
end

local FROM_RU = { key = "cmd_from_ru", what = "from RU", req = "CCI", ans = "CAO", link = "cmd_from_ru",
                  back = "cao_in" }
local TO_RU = { key = "cmd_to_ru", what = "to RU", req = "CCO", ans = "CAI", link = "cmd_to_ru",
                back = "cai_in" }
local NONE = {}

local function stall(r, st, value, t, frame, limit, name, key)
    local s = handshake.stall(st, value, t, frame, limit)
    local age = t - st.t
    if s and s.kind == "stalled" then
        r.findings[#r.findings + 1] = { key, string.format("%s %d has not changed for %.0f ms (since frame %d, "
            .. "limit %.0f ms)", name, s.value, s.age * 1000, s.since, limit * 1000) }
    end
    return age
end

function M.update(st, inp, out, t, frame, ref)
    inp, out = inp or NONE, out or NONE
    local r = { findings = {}, links = {}, back = {} }
    local lim = M.LIMITS
    commands(r, handshake.echo(st.from_ru, inp.cci, out.cao, t, frame, lim.cmd, ref), FROM_RU, frame)
    commands(r, handshake.echo(st.to_ru, out.cco, inp.cai, t, frame, lim.cmd, ref), TO_RU, frame)
    if inp.bu ~= nil then
        if st.bu ~= nil and st.bu ~= inp.bu then
            r.bu_state_prev = st.bu
            r.findings[#r.findings + 1] = { "bu_state_change", string.format("BU state %s -> %s", bu_name(st.bu),
                bu_name(inp.bu)) }
        end
        st.bu = inp.bu
    end
    if inp.pci ~= nil then
        r.pci_age = stall(r, st.pci, inp.pci, t, frame, lim.pci, "PCI", "pci_stalled")
    end
    if out.pco ~= nil then
        r.pco_age = stall(r, st.pco, out.pco, t, frame, lim.pco, "PCO", "pco_stalled")
    end
    return r
end

return M
