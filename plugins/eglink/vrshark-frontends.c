/* vrshark-frontends.c
 * Transport front ends of the vrshark Lua dissectors: Wireshark's own
 * dissector first, then the Lua decoder only for traffic that is ours or
 * still a candidate, so that foreign traffic never enters Lua.
 *
 *   EtherType 0x8892   protocol "vrshark_pnio": PN-RT (pn_rt) first, then
 *                      the FrameID (first 2 bytes):
 *                        in vrshark.pn.frame_id        -> that Lua decoder
 *                        0x8000..0xFBFF, first pass    -> hook "candidate",
 *                          at most VRSHARK_PN_CANDIDATE_TRIES refusals per
 *                          FrameID (unbounded while hook "pending" exists)
 *   UDP 34964 and the  a DCE/RPC connectionless request/response
 *   controllers' ports (version 4) goes to the UDP heuristics (DCE/RPC,
 *                      PNIO-CM); a Connect (opnum 0, unfragmented) then to
 *                      hook "connect". The source port of a Connect request
 *                      is added to udp.port for the response (until the
 *                      next file).
 *   Modbus/TCP port    "vrshark.mbtcp" (protocol "vrshark_mbtcp", which
 *   (the Lua side puts takes itself out of the layer list): mbtcp first,
 *   the front end on   then the Lua decoder registered in vrshark.mbtcp.hook
 *   its port)          as "always" (every connection), or as "heuristic":
 *                      a TCP connection (conversation) is a candidate until
 *                      the decoder accepts one of its frames (returns
 *                      non-zero); from then on every frame goes to it. After
 *                      VRSHARK_MB_CANDIDATE_TRIES refusals, first pass only,
 *                      the connection is left to mbtcp. On a port other
 *                      than 502 mbtcp is shown the server's port as 502
 *                      while it runs: it tells queries from responses by
 *                      its own port preference (default 502).
 *
 * The Lua side detects these tables (DissectorTable.get under pcall),
 * registers its decoders and the FrameIDs it learns into them, and stops
 * wrapping the dissectors itself; without this plugin it wraps them as
 * before. A Lua decoder returns 0 for a frame that is not (yet) its own;
 * that counts one try. Later passes call only the registered FrameIDs and
 * accepted connections (the Lua side keeps its per-frame decisions of the
 * first pass), so both passes agree.
 *
 * Known FrameIDs and accepted connections reach the decoder with
 * pinfo->match_string "frame_id" / "heuristic" / "always", or the same with
 * ".quiet" appended when nothing it would add can be seen: no column
 * information, an invisible tree, none of the Lua protocols' fields
 * referenced (display filter, -e, colouring rule, Lua Field), no expert info
 * wanted. The decoder then keeps its state (first pass) and adds nothing.
 *
 * Exceptions of the wrapped dissectors propagate as they would without the
 * front end.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "eglink-compat.h"

#include <epan/packet.h>
#include <epan/conversation.h>
#include <epan/tap.h>
#include <epan/exceptions.h>

#include "vrshark-frontends.h"

#define ETHERTYPE_PNRT          0x8892
#define UDP_PORT_PNIO_CM        34964
#define PN_CANDIDATE_FIRST      0x8000
#define PN_CANDIDATE_LAST       0xFBFF
#define PN_CANDIDATE_COUNT      (PN_CANDIDATE_LAST - PN_CANDIDATE_FIRST + 1)

/* DCE/RPC connectionless header (80 bytes) */
#define DCERPC_DG_HEADER_LEN    80
#define DCERPC_DG_VERSION       4
#define DCERPC_DG_REQUEST       0
#define DCERPC_DG_RESPONSE      2
#define DCERPC_DG_FLAGS1_FRAG   0x04
#define DCERPC_DG_DREP_LITTLE   0x10
#define DCERPC_DG_OPNUM_OFF     68
#define PNIO_CM_CONNECT         0
/* Connect: the header, the PNIO args (20) and at least one block header */
#define PNIO_CONNECT_MIN_LEN    (DCERPC_DG_HEADER_LEN + 20)

static int proto_vrshark_pnio = -1;
static int proto_vrshark_mbtcp = -1;

static dissector_handle_t pn_rt_handle;
static dissector_handle_t mbtcp_handle;
static dissector_handle_t pn_cyclic_handle;
static dissector_handle_t pn_cm_handle;

static dissector_table_t pn_frame_id_table;
static dissector_table_t pn_hook_table;
static dissector_table_t mb_hook_table;
static heur_dissector_list_t udp_heur_list;

/* Per file: refusals per candidate FrameID; per TCP connection. */
static guint8 pn_tries[PN_CANDIDATE_COUNT];
static wmem_map_t *mb_state;   /* conversation index -> refusals | MB_ACCEPTED */

/* UDP ports added for Connect responses; removed when the next file starts. */
static GArray *pn_learned_ports;

/* ---- Does anybody look at what the Lua decoder adds? ------------------- */

/* Filter names of the protocols whose fields the Lua decoders add, each list
 * ending with NULL; their ids are looked up on first use (the Lua plugins
 * register after this one). */
static const char *pn_lua_protos[] = { "mcmb2", "eclink_pnio", "eclink", "_ws.expert", NULL };
static const char *mb_lua_protos[] = { "eclink_modbus", "eclink", "_ws.expert", NULL };
static int pn_lua_ids[G_N_ELEMENTS(pn_lua_protos)];
static int mb_lua_ids[G_N_ELEMENTS(mb_lua_protos)];
static int expert_tap;         /* 0 until found (find_tap_id's "not registered") */

static gboolean
lua_output_wanted(packet_info *pinfo, proto_tree *tree, const char **names, int *ids)
{
    int i;

    /* Looked up here, not at hand-off: the expert tap is registered after
     * the plugins' hand-off, and find_tap_id() says 0 until then. */
    if (expert_tap <= 0)
        expert_tap = find_tap_id("expert");
    if (pinfo->cinfo || !tree || have_tap_listener(expert_tap))
        return pinfo->cinfo || have_tap_listener(expert_tap);
    for (i = 0; names[i]; i++) {
        if (ids[i] == 0)
            ids[i] = proto_get_id_by_filter_name(names[i]) + 1;  /* 0: not looked up yet */
        if (ids[i] > 0 && proto_field_is_referenced(tree, ids[i] - 1))
            return TRUE;
    }
    return FALSE;
}

/* ---- PROFINET cyclic frames (EtherType 0x8892) ------------------------- */

static int
dissect_pn_cyclic(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree, void *data)
{
    int consumed = call_dissector_only(pn_rt_handle, tvb, pinfo, tree, data);
    guint16 fid;
    guint idx;

    if (tvb_captured_length(tvb) < 2)
        return consumed;
    fid = tvb_get_ntohs(tvb, 0);
    if (dissector_get_uint_handle(pn_frame_id_table, fid)) {
        const char *saved = pinfo->match_string;

        pinfo->match_string = lua_output_wanted(pinfo, tree, pn_lua_protos, pn_lua_ids) ?
            "frame_id" : "frame_id.quiet";
        dissector_try_uint_with_data(pn_frame_id_table, fid, tvb, pinfo, tree, FALSE, NULL);
        pinfo->match_string = saved;
        return consumed;
    }
    if (fid < PN_CANDIDATE_FIRST || fid > PN_CANDIDATE_LAST || pinfo->fd->visited)
        return consumed;
    idx = fid - PN_CANDIDATE_FIRST;
    if (pn_tries[idx] >= VRSHARK_PN_CANDIDATE_TRIES &&
        !dissector_get_string_handle(pn_hook_table, "pending"))
        return consumed;
    if (!dissector_try_string_with_data(pn_hook_table, "candidate", tvb, pinfo, tree, FALSE, NULL) &&
        pn_tries[idx] < VRSHARK_PN_CANDIDATE_TRIES)
        pn_tries[idx]++;
    return consumed;
}

/* ---- PNIO-CM (DCE/RPC over UDP) ----------------------------------------- */

static gboolean
is_dcerpc_dg(tvbuff_t *tvb)
{
    guint8 ptype;

    if (tvb_captured_length(tvb) < DCERPC_DG_HEADER_LEN || tvb_get_uint8(tvb, 0) != DCERPC_DG_VERSION)
        return FALSE;
    ptype = tvb_get_uint8(tvb, 1);
    return ptype == DCERPC_DG_REQUEST || ptype == DCERPC_DG_RESPONSE;
}

static gboolean
is_connect(tvbuff_t *tvb)
{
    guint encoding;

    if (tvb_captured_length(tvb) < PNIO_CONNECT_MIN_LEN)
        return FALSE;
    if (tvb_get_uint8(tvb, 2) & DCERPC_DG_FLAGS1_FRAG)
        return FALSE;
    encoding = (tvb_get_uint8(tvb, 4) & DCERPC_DG_DREP_LITTLE) ? ENC_LITTLE_ENDIAN : ENC_BIG_ENDIAN;
    return tvb_get_uint16(tvb, DCERPC_DG_OPNUM_OFF, encoding) == PNIO_CM_CONNECT;
}

/* The response to a Connect request comes from the device's own port to
 * the controller's: take that port too (unless something else has it). */
static void
learn_controller_port(packet_info *pinfo)
{
    guint32 port = pinfo->srcport;

    if (port == UDP_PORT_PNIO_CM || port == 0 || dissector_get_uint_handle(find_dissector_table("udp.port"), port))
        return;
    dissector_add_uint("udp.port", port, pn_cm_handle);
    g_array_append_val(pn_learned_ports, port);
}

static int
dissect_pn_cm(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree, void *data)
{
    heur_dtbl_entry_t *hdtbl_entry;

    if (!is_dcerpc_dg(tvb))
        return 0;
    if (!dissector_try_heuristic(udp_heur_list, tvb, pinfo, tree, &hdtbl_entry, data))
        return 0;
    if (is_connect(tvb) && dissector_get_string_handle(pn_hook_table, "connect")) {
        if (!pinfo->fd->visited && tvb_get_uint8(tvb, 1) == DCERPC_DG_REQUEST)
            learn_controller_port(pinfo);
        dissector_try_string_with_data(pn_hook_table, "connect", tvb, pinfo, tree, FALSE, NULL);
    }
    return tvb_captured_length(tvb);
}

/* ---- Modbus/TCP ----------------------------------------------------------- */

#define MB_ACCEPTED 0x80000000u
#define MBTCP_DEFAULT_PORT 502

/* Removes the front end's own entry from the layer list: Modbus/TCP looks as
 * without it (tcp:mbtcp:modbus), and mbtcp gets the layer number it would
 * have had. The Lua decoder adds its own name when it decodes the frame. */
static void
leave_layer_list(packet_info *pinfo)
{
    wmem_list_frame_t *last = wmem_list_tail(pinfo->layers);

    if (last && GPOINTER_TO_INT(wmem_list_frame_data(last)) == proto_vrshark_mbtcp) {
        wmem_list_remove_frame(pinfo->layers, last);
        pinfo->curr_layer_num--;
    }
}

/* The Lua decoder registered as `mode` ("always" or "heuristic"), with
 * pinfo->match_string `mode` or, when nothing it adds would be seen,
 * `mode`.quiet. Its protocol joins the layer list, as when it wraps mbtcp
 * itself. */
static int
call_mb_decoder(const char *mode, gboolean quiet, tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree)
{
    const char *saved = pinfo->match_string;
    int ret;

    if (quiet)
        pinfo->match_string = (strcmp(mode, "always") == 0) ? "always.quiet" : "heuristic.quiet";
    else
        pinfo->match_string = mode;
    ret = call_dissector_only(dissector_get_string_handle(mb_hook_table, mode), tvb, pinfo, tree, NULL);
    pinfo->match_string = saved;
    return ret;
}

/* mbtcp classifies an ADU as query or response by its own TCP port
 * preference (default 502). On another port it is shown the server's port
 * as 502 while it runs, so that one setting (eclink_modbus.port) is enough. */
static int
call_mbtcp(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree, void *data)
{
    guint32 bu_port = pinfo->match_uint;
    guint32 srcport = pinfo->srcport, destport = pinfo->destport;
    gboolean moved = bu_port != MBTCP_DEFAULT_PORT && (srcport == bu_port) != (destport == bu_port) &&
                     srcport != MBTCP_DEFAULT_PORT && destport != MBTCP_DEFAULT_PORT;
    volatile int consumed = 0;

    if (!moved)
        return call_dissector_only(mbtcp_handle, tvb, pinfo, tree, data);
    if (destport == bu_port)
        pinfo->destport = MBTCP_DEFAULT_PORT;
    else
        pinfo->srcport = MBTCP_DEFAULT_PORT;
    TRY {
        consumed = call_dissector_only(mbtcp_handle, tvb, pinfo, tree, data);
    }
    FINALLY {
        pinfo->srcport = srcport;
        pinfo->destport = destport;
    }
    ENDTRY;
    return consumed;
}

static int
dissect_mbtcp_front(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree, void *data)
{
    conversation_t *conv;
    gpointer key;
    guint32 state;
    int consumed;
    const char *mode;
    gboolean quiet;

    leave_layer_list(pinfo);
    /* mbtcp may use TCP desegmentation as if TCP had called it directly */
    if (pinfo->can_desegment > 0)
        pinfo->can_desegment++;
    consumed = call_mbtcp(tvb, pinfo, tree, data);
    if (consumed <= 0)
        return consumed;
    quiet = !lua_output_wanted(pinfo, tree, mb_lua_protos, mb_lua_ids);
    if (dissector_get_string_handle(mb_hook_table, "always")) {
        call_mb_decoder("always", quiet, tvb, pinfo, tree);
        return consumed;
    }
    mode = "heuristic";
    if (!dissector_get_string_handle(mb_hook_table, mode) || !(conv = find_conversation_pinfo(pinfo, 0)))
        return consumed;
    key = GUINT_TO_POINTER(conv->conv_index);
    state = GPOINTER_TO_UINT(wmem_map_lookup(mb_state, key));
    if (state & MB_ACCEPTED) {
        call_mb_decoder(mode, quiet, tvb, pinfo, tree);
        return consumed;
    }
    /* a candidate: later passes keep the first pass's refusals */
    if (pinfo->fd->visited || state >= VRSHARK_MB_CANDIDATE_TRIES)
        return consumed;
    if (call_mb_decoder(mode, FALSE, tvb, pinfo, tree))
        state = MB_ACCEPTED;
    else
        state++;
    wmem_map_insert(mb_state, key, GUINT_TO_POINTER(state));
    return consumed;
}

/* ---- Registration ----------------------------------------------------------- */

static void
frontends_init(void)
{
    guint i;

    memset(pn_tries, 0, sizeof pn_tries);
    mb_state = wmem_map_new(wmem_file_scope(), g_direct_hash, g_direct_equal);
    for (i = 0; i < pn_learned_ports->len; i++)
        dissector_delete_uint("udp.port", g_array_index(pn_learned_ports, guint32, i), pn_cm_handle);
    g_array_set_size(pn_learned_ports, 0);
}

static void
frontends_shutdown(void)
{
    g_array_free(pn_learned_ports, TRUE);
}

void
proto_register_vrshark_frontends(void)
{
    proto_vrshark_pnio = proto_register_protocol("vrshark PROFINET IO cyclic data", "vrshark_pnio",
                                                 "vrshark_pnio");
    pn_cyclic_handle = register_dissector("vrshark_pnio", dissect_pn_cyclic, proto_vrshark_pnio);
    pn_cm_handle = register_dissector("vrshark_pnio.cm", dissect_pn_cm, proto_vrshark_pnio);
    proto_vrshark_mbtcp = proto_register_protocol("vrshark Modbus/TCP front end", "vrshark_mbtcp",
                                                  "vrshark_mbtcp");
    register_dissector(VRSHARK_MB_FRONT_NAME, dissect_mbtcp_front, proto_vrshark_mbtcp);

    pn_frame_id_table = register_dissector_table(VRSHARK_PN_FRAME_ID_TABLE,
        "vrshark: PROFINET cyclic FrameIDs decoded in Lua", proto_vrshark_pnio, FT_UINT16, BASE_HEX);
    pn_hook_table = register_dissector_table(VRSHARK_PN_HOOK_TABLE,
        "vrshark: PROFINET candidates and Connects for Lua", proto_vrshark_pnio, FT_STRING,
        FALSE /* case-sensitive */);
    mb_hook_table = register_dissector_table(VRSHARK_MB_HOOK_TABLE,
        "vrshark: Modbus/TCP connections for Lua", proto_vrshark_mbtcp, FT_STRING, FALSE /* case-sensitive */);

    pn_learned_ports = g_array_new(FALSE, FALSE, sizeof(guint32));
    register_init_routine(frontends_init);
    register_shutdown_routine(frontends_shutdown);
}

void
proto_reg_handoff_vrshark_frontends(void)
{
    dissector_table_t ethertype = find_dissector_table("ethertype");

    pn_rt_handle = dissector_get_uint_handle(ethertype, ETHERTYPE_PNRT);
    if (!pn_rt_handle)
        pn_rt_handle = find_dissector_add_dependency("pn_rt", proto_vrshark_pnio);
    mbtcp_handle = find_dissector_add_dependency("mbtcp", proto_vrshark_mbtcp);
    udp_heur_list = find_heur_dissector_list("udp");
    dissector_add_uint("ethertype", ETHERTYPE_PNRT, pn_cyclic_handle);
    dissector_add_uint("udp.port", UDP_PORT_PNIO_CM, pn_cm_handle);
}
