-- vrshark.handshake: counter supervision shared by the fieldbus dissectors.
--
-- Two kinds of rule, both evaluated on the first pass in frame order, their
-- results stored per frame by the caller:
--
--   stall(state, value, t, frame, limit)
--     A counter that must move at least every `limit` seconds (an MC-MB2
--     watchdog, EC-Link PCI/PCO). Returns a finding the first time the counter
--     has kept one value for longer than `limit`:
--       { kind = "stalled", age = seconds, since = frame, value = v }
--     and, when it moves again after such a finding:
--       { kind = "resumed", age = seconds, since = frame, value = old }
--
--   echo(state, request, answer, t, frame, limit, ref)
--     A request counter (EC-Link CCI, CCO) whose new value the other side must
--     copy into its acknowledge counter (CAO, CAI) within `limit` seconds.
--     `request` is the latest request counter seen (nil when this frame does
--     not carry it), `answer` the latest acknowledge (nil likewise); `ref` is
--     anything the caller wants back with the answer (its record of the
--     request frame). Returns a list of:
--       { kind = "new", value = v, old = previous }       a new request
--       { kind = "acked", value = v, delay = s, since = frame, ref = ref }
--                                                       answered in time
--       { kind = "late", value = v, age = s, since = frame, ref = ref }
--                                  deadline passed, not answered (once)
--       { kind = "acked_late", value = v, delay = s, since = frame, ref = ref,
--         reported = whether "late" was returned before }
--                                                       answered after `limit`
--
-- `state` is a table owned by the caller (one per counter and conversation);
-- the module keeps nothing itself and has no side effects at load time.
local M = {}

function M.stall(st, value, t, frame, limit)
    if st.value == nil then
        st.value, st.t, st.frame, st.flagged = value, t, frame, false
        return nil
    end
    if value ~= st.value then
        local res
        if st.flagged then
            res = { kind = "resumed", age = t - st.t, since = st.frame, value = st.value }
        end
        st.value, st.t, st.frame, st.flagged = value, t, frame, false
        return res
    end
    if not st.flagged and t - st.t > limit then
        st.flagged = true
        return { kind = "stalled", age = t - st.t, since = st.frame, value = value }
    end
    return nil
end

-- Returns a list (possibly empty) of findings for this frame.
function M.echo(st, request, answer, t, frame, limit, ref)
    local out = {}
    if request ~= nil then
        if st.request == nil then
            -- The first value is the baseline, not a new request.
            st.request = request
        elseif request ~= st.request then
            out[#out + 1] = { kind = "new", value = request, old = st.request }
            st.request = request
            st.pending = { value = request, t = t, frame = frame, late = false, ref = ref }
        end
    end
    local p = st.pending
    if p then
        if answer ~= nil and answer == p.value then
            st.pending = nil
            local delay = t - p.t
            out[#out + 1] = { kind = (p.late or delay > limit) and "acked_late" or "acked", value = p.value,
                              delay = delay, since = p.frame, ref = p.ref, reported = p.late }
        elseif not p.late and t - p.t > limit then
            p.late = true
            out[#out + 1] = { kind = "late", value = p.value, age = t - p.t, since = p.frame, ref = p.ref }
        end
    end
    return out
end

return M
