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
 *                          FrameID (unbounded while flag "pending" is on)
 *   UDP 34964 and the  a DCE/RPC connectionless request/response
 *   controllers' ports (version 4) goes to the UDP heuristics (DCE/RPC,
 *                      PNIO-CM); a Connect (opnum 0, whole or a fragment)
 *                      then to hook "connect" (while flag "response" is
 *                      off, i.e. the carrier holds no AR learned from a
 *                      request: no response, and no request whose expected
 *                      submodule blocks it returned 0 for before). The
 *                      source port of a Connect request is added to
 *                      udp.port for the response (until the next file).
 *   Modbus/TCP ports   "vrshark.mbtcp" (protocol "vrshark_mbtcp", which
 *   (eclink_modbus.    takes itself out of the layer list): mbtcp first,
 *   port, a range,     then the Lua decoder registered in vrshark.mbtcp.hook
 *   and mbtcp's own)   as "always" (every connection), or as "heuristic":
 *                      a TCP connection (its two addresses and ports, as
 *                      the Lua side keys it: mb_conn_key_t) becomes a
 *                      candidate when its client first asks for what a BU's image
 *                      evidence needs (the whole input image read, or the
 *                      output image written: mb_evidence_request), and stays
 *                      one until the decoder accepts one of its frames (returns
 *                      non-zero); from then on every frame goes to it. After
 *                      VRSHARK_MB_CANDIDATE_TRIES refusals, first pass only,
 *                      the connection is left to mbtcp. On a port other
 *                      than mbtcp's own (mbtcp.tcp.port) mbtcp is shown the
 *                      server's port as its own while it runs: it tells
 *                      queries from responses by that preference.
 *                      A server the user listed (eclink_modbus.servers: the
 *                      Lua side says the list, "server ADDR:PORT" or
 *                      "server ADDR" each, and registers hook "server"
 *                      while any is listed) goes to the decoder from its
 *                      first frame as hook "server", whatever the
 *                      detection; the Lua
 *                      side also puts this front end on the ports its
 *                      entries name. On later passes the frames a candidate
 *                      handed to "heuristic" on the first pass go there
 *                      again, for the notes on its candidate frames (the
 *                      decoder adds nothing else to them).
 *   TCP heuristic      a request on a port no dissector took whose MBAP
 *   (any other port)   headers fill the segment and that carries a BU's
 *                      evidence (mb_evidence_request): Lua hook "port_hint"
 *                      (the note with the setting that decodes its server).
 *                      Asked before Wireshark's own TCP heuristics (rpcap
 *                      takes some Modbus requests for its own and fails).
 *
 * Table entries are taken again when each file starts (own_pn_rt,
 * own_pn_cm, own_mb_port): the order of plugin hand-offs depends on the
 * folders the plugins sit in, and a later hand-off replaces an entry.
 * The flags "pending" and "response" and the list of servers are the Lua
 * side's state, set by it the moment they change (vrshark-flags.c); the
 * Modbus hooks are read again when it says it changed them
 * (mb_read_hooks). Nothing looked up of the Lua side (protocol ids,
 * fields, hooks) outlives a file either: Analyze > Reload Lua Plugins
 * registers it all anew under other ids and then dissects anew
 * (forget_lua_side).
 *
 * The Lua side detects these tables (DissectorTable.get under pcall),
 * registers its decoders and the FrameIDs it learns into them, and stops
 * wrapping the dissectors itself; without this plugin it wraps them as
 * before. A Lua decoder returns 0 for a frame that is not (yet) its own;
 * that counts one try. Later passes call only the registered FrameIDs and
 * accepted connections (the Lua side keeps its per-frame decisions of the
 * first pass), so both passes agree.
 *
 * Known FrameIDs, accepted connections and listed servers reach the decoder
 * with pinfo->match_string "frame_id" / "heuristic" / "always" / "server"
 * (the view grammar of vrshark-frontends.h, decoded by seam.luam's view())
 * when the tree is visible, or the same with ".quiet" appended when nothing
 * it would add can be seen (it then keeps its state and adds nothing), or with ".sparse:..."
 * naming what is looked at in an invisible tree: columns, expert info, the
 * referenced fields (lua_view below). Every item of an invisible tree that
 * nobody references is thrown away by Wireshark: the decoder need not build
 * it. VRSHARK_FULL_TREE in the environment turns this off (everything).
 *
 * Exceptions of the wrapped dissectors propagate as they would without the
 * front end, except PN-RT's on a known FrameID (call_pn_rt_known): shown,
 * and the frame still goes to the decoder as "frame_id.malformed".
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "eglink-compat.h"

#include <epan/packet.h>
#include <epan/tap.h>
#include <epan/exceptions.h>
#include <epan/expert.h>
#include <epan/prefs.h>
#include <epan/to_str.h>
#include <epan/proto_data.h>
#include <epan/show_exception.h>

#include "vrshark-columns.h"
#include "vrshark-flags.h"
#include "vrshark-frontends.h"
#include "vrshark-tcpends.h"
#include "vrshark-output.h"

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

static expert_field ei_pn_taken = EI_INIT;

static dissector_handle_t pn_rt_handle;
static dissector_handle_t mbtcp_handle;
static dissector_handle_t pn_cyclic_handle;
static dissector_handle_t pn_cm_handle;
static dissector_handle_t mb_front_handle;

static dissector_table_t pn_frame_id_table;
static dissector_table_t pn_hook_table;

static dissector_table_t mb_hook_table;
static heur_dissector_list_t udp_heur_list;

/* Per file: refusals per candidate FrameID; per TCP connection. */
static guint8 pn_tries[PN_CANDIDATE_COUNT];
static wmem_map_t *mb_state;   /* mb_conn_key_t -> refusals | MB_ACCEPTED */

/* UDP ports added for Connect responses; removed when the next file starts. */
static GArray *pn_learned_ports;

/* ---- What does anybody see of what the Lua decoder adds? ----------------- */

/* Filter names of the protocols whose fields the Lua decoders add, each list
 * ending with NULL; their ids are looked up on first use (the Lua plugins
 * register after this one). */
static const char *pn_lua_protos[] = { "mcmb2", "eclink_pnio", "eclink", "vrshark_io", NULL };
static const char *mb_lua_protos[] = { "eclink_modbus", "eclink", "vrshark_io", NULL };
#define VIEW_MAX_PROTOS 4

/* What the Lua decoder is told, per hook name (see the file comment). */
typedef struct {
    const char *hook;               /* "frame_id", "heuristic", "always" */
    const char **protos;            /* pn_lua_protos or mb_lua_protos */
    int ids[VIEW_MAX_PROTOS];       /* protocol id + 1; 0: not looked up yet */
    char *quiet;                    /* hook ".quiet" */
    GArray *refs;                   /* header_field_info * of the last sparse view */
    gboolean cols, experts, items;  /* ... and its flags (items: protocol items wanted) */
    char *sparse;                   /* hook ".sparse:FLAGS:LIST" of that view */
    GPtrArray *fields[VIEW_MAX_PROTOS]; /* header_field_info * of each protocol's fields,
                                         * in registration order; made when first walked,
                                         * dropped when a file starts (view_fields) */
} lua_view_t;

static lua_view_t view_pn = { VRSHARK_VIEW_FRAME_ID, pn_lua_protos, { 0 }, NULL, NULL, FALSE, FALSE, FALSE, NULL, { NULL } };
static lua_view_t view_mb_always = { VRSHARK_MB_HOOK_ALWAYS, mb_lua_protos, { 0 }, NULL, NULL, FALSE, FALSE, FALSE, NULL,
                                     { NULL } };
static lua_view_t view_mb_heuristic = { VRSHARK_MB_HOOK_HEURISTIC, mb_lua_protos, { 0 }, NULL, NULL, FALSE, FALSE, FALSE, NULL,
                                        { NULL } };
static lua_view_t view_mb_server = { VRSHARK_MB_HOOK_SERVER, mb_lua_protos, { 0 }, NULL, NULL, FALSE, FALSE, FALSE, NULL,
                                     { NULL } };

/* The Lua decoder's Modbus hooks ("always", "heuristic", "server"), looked up
 * again only when the Lua side says it changed them
 * (vrshark_mb_hooks_changes, vrshark-flags.c), or on every frame where it
 * cannot say so. Three lookups by string a frame were most of what the
 * front end cost a Modbus/TCP connection that is no BU's. */
static struct {
    guint changes;      /* vrshark_mb_hooks_changes when read; 0: not read */
    dissector_handle_t always, heuristic, server;
} mb_hooks;

static void
mb_read_hooks(void)
{
    if (mb_hooks.changes && mb_hooks.changes == vrshark_mb_hooks_changes)
        return;
    mb_hooks.always = dissector_get_string_handle(mb_hook_table, view_mb_always.hook);
    mb_hooks.heuristic = dissector_get_string_handle(mb_hook_table, view_mb_heuristic.hook);
    mb_hooks.server = dissector_get_string_handle(mb_hook_table, view_mb_server.hook);
    mb_hooks.changes = vrshark_mb_hooks_changes;
}

static GArray *view_scratch;   /* lua_view()'s list of this frame */
static GArray *named_fields;   /* tshark -T fields: its -e fields (header_field_info *) */
static gboolean named_other;   /* ... and a -e value that is no field name: everything */
static int expert_tap;         /* 0 until found (find_tap_id's "not registered") */
static int proto_ws_expert;    /* id + 1; 0: not looked up yet */
static gboolean full_tree_always;   /* VRSHARK_FULL_TREE set: every view is "everything" */

static int
lookup_proto(int *slot, const char *name)
{
    if (*slot == 0)
        *slot = proto_get_id_by_filter_name(name) + 1;
    return *slot - 1;
}

/* Referenced, in the sense proto_tree_add_*() use to decide whether an item
 * of an invisible tree is real: DIRECT (or PRINT, from 4.2 on), not the
 * INDIRECT a protocol gets from its children. */
static gboolean
hf_referenced(const header_field_info *hfinfo)
{
    return hfinfo->ref_type != HF_REF_TYPE_NONE && hfinfo->ref_type != HF_REF_TYPE_INDIRECT;
}

/* The fields of protocol i of the view (id), walked once per file: the Lua
 * plugins register theirs when they load, and a reload of them is followed
 * by a new dissection (frontends_init() drops the lists). */
static GPtrArray *
view_fields(lua_view_t *v, int i, int id)
{
    if (!v->fields[i]) {
        header_field_info *hfinfo;
        void *cookie = NULL;

        v->fields[i] = g_ptr_array_new();
        for (hfinfo = proto_get_first_protocol_field(id, &cookie); hfinfo;
             hfinfo = proto_get_next_protocol_field(id, &cookie))
            g_ptr_array_add(v->fields[i], hfinfo);
    }
    return v->fields[i];
}

static void
view_fields_drop(lua_view_t *v)
{
    int i;

    for (i = 0; i < VIEW_MAX_PROTOS; i++) {
        if (v->fields[i])
            g_ptr_array_free(v->fields[i], TRUE);
        v->fields[i] = NULL;
    }
}

/* The referenced fields of the view's protocols (the protocols themselves
 * included) into refs. Priming a field for a filter, a column or printing
 * marks its protocol too (INDIRECT, or DIRECT when named itself), and the
 * marks are cleared with the tree: the fields of a protocol left unmarked
 * are not walked (a walk costs a few thousand instructions a frame). */
static void
collect_refs(lua_view_t *v, GArray *refs)
{
    int i;

    for (i = 0; v->protos[i]; i++) {
        int id = lookup_proto(&v->ids[i], v->protos[i]);
        header_field_info *hfinfo;
        GPtrArray *fields;
        guint f;

        if (id < 0)
            continue;
        hfinfo = proto_registrar_get_nth(id);
        if (!hfinfo || hfinfo->ref_type == HF_REF_TYPE_NONE)
            continue;
        if (hf_referenced(hfinfo))
            g_array_append_val(refs, hfinfo);
        fields = view_fields(v, i, id);
        for (f = 0; f < fields->len; f++) {
            hfinfo = (header_field_info *)g_ptr_array_index(fields, f);
            if (hf_referenced(hfinfo))
                g_array_append_val(refs, hfinfo);
        }
    }
}

/* tshark -T fields: the fields its -e options name, resolved once (the
 * Lua plugins have registered theirs by the first frame). tshark marks
 * them referenced only on an invisible tree; columns (_ws.col.*) come
 * with pinfo->cinfo. */
static void
resolve_named(void)
{
    const GPtrArray *names = vrshark_fields_named();
    guint i;

    named_fields = g_array_new(FALSE, FALSE, sizeof(header_field_info *));
    for (i = 0; i < names->len; i++) {
        const char *name = (const char *)g_ptr_array_index(names, i);
        header_field_info *hfinfo;

        if (g_str_has_prefix(name, "_ws.col."))
            continue;
        hfinfo = proto_registrar_get_byname(name);
        if (hfinfo)
            g_array_append_val(named_fields, hfinfo);
        else
            named_other = TRUE;
    }
}

/* Is hfinfo the protocol id or one of its fields? */
static gboolean
of_protocol(const header_field_info *hfinfo, int id)
{
    return id >= 0 && (hfinfo->id == id || hfinfo->parent == id);
}

/* The -e fields of the view's protocols into refs; TRUE in *experts when
 * one is an expert info field. FALSE: a -e value was no field name (an
 * expression, say), so that what it reads is not known. */
static gboolean
collect_named(lua_view_t *v, GArray *refs, int ws_expert, gboolean *experts)
{
    guint i;
    int p;

    if (!named_fields)
        resolve_named();
    if (named_other)
        return FALSE;
    for (i = 0; i < named_fields->len; i++) {
        header_field_info *hfinfo = g_array_index(named_fields, header_field_info *, i);

        if (of_protocol(hfinfo, ws_expert))
            *experts = TRUE;
        for (p = 0; v->protos[p]; p++) {
            if (of_protocol(hfinfo, lookup_proto(&v->ids[p], v->protos[p]))) {
                g_array_append_val(refs, hfinfo);
                break;
            }
        }
    }
    return TRUE;
}

/* pinfo->match_string for the Lua decoder behind hook v->hook:
 *   v->hook                   everything: the tree is visible (a packet's
 *                             details, -V, -T pdml/json), protocols are not
 *                             faked (Protocol Hierarchy), or VRSHARK_FULL_TREE
 *   v->hook ".quiet"          nothing can be seen: no column information, no
 *                             expert info wanted, none of the Lua protocols'
 *                             fields referenced; the decoder keeps its state
 *   v->hook ".sparse:FLAGS:LIST"  an invisible tree (the packet list, -Y),
 *                             or tshark -T fields (vrshark-output.c): only
 *                             what is asked for. FLAGS: "c"
 *                             column information wanted, "e" expert info
 *                             wanted (an expert tap, a _ws.expert field
 *                             referenced), "p" the protocol items wanted (a
 *                             tap wants the tree); LIST: the filter names of the
 *                             referenced fields of the Lua protocols (display
 *                             filter, -e, colouring rule, Lua Field), comma
 *                             separated, in registration order.
 * The sparse text is rebuilt only when the flags or the list change. */
static const char *
lua_view(lua_view_t *v, packet_info *pinfo, proto_tree *tree)
{
    GArray *refs;
    gboolean cols, experts, items, fields_only = FALSE;
    guint i;

    /* A visible tree is seen whole, but for tshark -T fields (only what
     * -e names is printed); so is one that fakes no protocols (Statistics >
     * Protocol Hierarchy in the GUI). */
    if (full_tree_always || (tree && !PTREE_DATA(tree)->fake_protocols))
        return v->hook;
    if (tree && PTREE_DATA(tree)->visible) {
        if (!vrshark_fields_only())
            return v->hook;
        fields_only = TRUE;
    }
    /* Looked up here, not at hand-off: the expert tap is registered after
     * the plugins' hand-off, and find_tap_id() says 0 until then. */
    if (expert_tap <= 0)
        expert_tap = find_tap_id("expert");
    cols = pinfo->cinfo != NULL;
    experts = have_tap_listener(expert_tap);
    /* A tap that wants the protocol tree may walk its top level: -z io,phs
     * counts the protocol items there (a Lua Listener and -z io,stat ask
     * for the tree too). Protocol items at the top are never faked. */
    items = tree && (union_of_tap_listener_flags() & TL_REQUIRES_PROTO_TREE);
    if (!view_scratch)
        view_scratch = g_array_new(FALSE, FALSE, sizeof(header_field_info *));
    refs = view_scratch;
    g_array_set_size(refs, 0);
    if (tree) {
        int ws_expert = lookup_proto(&proto_ws_expert, "_ws.expert");

        /* (the protocol's own mark: proto_field_is_referenced() says yes
         * to anything on a visible tree) */
        if (ws_expert >= 0 && proto_registrar_get_nth(ws_expert)->ref_type != HF_REF_TYPE_NONE)
            experts = TRUE;
        collect_refs(v, refs);
        if (fields_only && !collect_named(v, refs, ws_expert, &experts))
            return v->hook;
    }
    if (!cols && !experts && !items && refs->len == 0) {
        if (!v->quiet)
            v->quiet = g_strconcat(v->hook, VRSHARK_VIEW_QUIET, NULL);
        return v->quiet;
    }
    /* (an empty GArray may have no data: memcmp() must not see it) */
    if (v->sparse && v->cols == cols && v->experts == experts && v->items == items && v->refs->len == refs->len &&
        (refs->len == 0 || memcmp(v->refs->data, refs->data, refs->len * sizeof(header_field_info *)) == 0))
        return v->sparse;
    {
        GString *text = g_string_new(v->hook);

        g_string_append_printf(text, VRSHARK_VIEW_SPARSE "%s%s%s:", cols ? VRSHARK_VIEW_FLAG_COLS : "",
                               experts ? VRSHARK_VIEW_FLAG_EXPERTS : "", items ? VRSHARK_VIEW_FLAG_PROTOS : "");
        for (i = 0; i < refs->len; i++)
            g_string_append_printf(text, "%s%s", i ? VRSHARK_VIEW_LIST_SEP : "",
                                   g_array_index(refs, header_field_info *, i)->abbrev);
        g_free(v->sparse);
        v->sparse = g_string_free(text, FALSE);
    }
    if (!v->refs)
        v->refs = g_array_new(FALSE, FALSE, sizeof(header_field_info *));
    g_array_set_size(v->refs, 0);
    if (refs->len)
        g_array_append_vals(v->refs, refs->data, refs->len);
    v->cols = cols;
    v->experts = experts;
    v->items = items;
    return v->sparse;
}

static void
lua_view_free(lua_view_t *v)
{
    view_fields_drop(v);
    g_free(v->quiet);
    g_free(v->sparse);
    if (v->refs)
        g_array_free(v->refs, TRUE);
    v->quiet = v->sparse = NULL;
    v->refs = NULL;
}

/* ---- PROFINET cyclic frames (EtherType 0x8892) ------------------------- */

/* A Lua decoder, with the column writers pointed at this frame while it
 * runs (vrshark-columns.c), also when it throws. */
static int
call_lua_decoder(dissector_handle_t h, tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree)
{
    packet_info *outer = vrshark_columns_enter(pinfo);
    volatile int ret = 0;

    TRY {
        ret = call_dissector_only(h, tvb, pinfo, tree, NULL);
    }
    FINALLY {
        vrshark_columns_leave(outer);
    }
    ENDTRY;
    return ret;
}

/* The Lua decoder h of FrameID fid (vrshark.pn.frame_id), the same way.
 * The carrier (mcmb2's Proto, the first of pn_lua_protos) runs as a front
 * end's hook, not a layer of its own; a decoder's own Proto (eclink_pnio,
 * under which the carrier registers the FrameIDs only it decodes) is a
 * layer, as its dissector called from Lua would be: frame.protocols and
 * Statistics > Protocol Hierarchy end with it, and its findings are filed
 * under it. */
static void
call_lua_frame_id(dissector_handle_t h, guint16 fid, tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree)
{
    packet_info *outer = vrshark_columns_enter(pinfo);
    gboolean layer = dissector_handle_get_protocol_index(h) != lookup_proto(&view_pn.ids[0], view_pn.protos[0]);

    TRY {
        dissector_try_uint_with_data(pn_frame_id_table, fid, tvb, pinfo, tree, layer, NULL);
    }
    FINALLY {
        vrshark_columns_leave(outer);
    }
    ENDTRY;
}

/* PN-RT (and PNIO below it) on a frame of a FrameID the Lua side knows: an
 * exception is shown where it happened and the frame still goes to the
 * decoder, as hook "frame_id.malformed" (everything shown). Wireshark 4.6
 * reads an RT_CLASS_1 frame as secured when two C-SDU bytes equal a length
 * it expects, and PNIO, knowing the IOCR from the Connect, then throws; the
 * Connect's layout fits the frame all the same (the decoder says so). A
 * frame the capture cut throws too; the decoder says that instead. */
static int
call_pn_rt_known(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree, void *data, gboolean *thrown)
{
    volatile int consumed = 0;

    *thrown = FALSE;
    if (!pn_rt_handle)
        return 0;
    TRY {
        consumed = call_dissector_only(pn_rt_handle, tvb, pinfo, tree, data);
    }
    /* (bounds errors too: a frame the capture cut, snaplen, goes to the
     * decoder, which decodes the bytes captured and says it was cut) */
    CATCH_BOUNDS_AND_DISSECTOR_ERRORS {
        show_exception(tvb, pinfo, tree, EXCEPT_CODE, GET_MESSAGE);
        *thrown = TRUE;
    }
    ENDTRY;
    return consumed;
}

/* ---- The clock ------------------------------------------------------------ */

/* Lua's clock (hook VRSHARK_PN_HOOK_CLOCK) on this frame, when it wants it
 * (vrshark_clock_wanted: a deadline passed, or a frame marked): a stream
 * that stopped is said on the first frame after its deadline, whichever
 * device or transport sent it. Every front end calls it after its own
 * work, also for a frame it gave to a Lua decoder (which has ticked the
 * clock itself: Lua does nothing the second time), so no path is missed. */
static void
clock_tick(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree)
{
    dissector_handle_t h;
    const char *saved;

    if (!vrshark_clock_wanted(pinfo) || !(h = dissector_get_string_handle(pn_hook_table, VRSHARK_PN_HOOK_CLOCK)))
        return;
    saved = pinfo->match_string;
    pinfo->match_string = VRSHARK_PN_HOOK_CLOCK;
    call_lua_decoder(h, tvb, pinfo, tree);
    pinfo->match_string = saved;
}

/* The TCP segments that ended a connection the Modbus decoder named, kept
 * since the last frame (vrshark-tcpends.c), handed to it before a front
 * end's own work on this frame: it arms their findings for this frame's
 * tick, as its own TCP listener would. */
static void
tcp_ends_deliver(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree)
{
    dissector_handle_t h;
    const char *saved;

    if (!vrshark_tcp_ends_pending)
        return;
    if (!(h = dissector_get_string_handle(mb_hook_table, VRSHARK_MB_HOOK_TCP_END))) {
        vrshark_tcp_ends_reset();
        return;
    }
    saved = pinfo->match_string;
    pinfo->match_string = VRSHARK_MB_HOOK_TCP_END;
    call_lua_decoder(h, tvb, pinfo, tree);
    pinfo->match_string = saved;
}

static int
pn_cyclic(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree, void *data)
{
    int consumed;
    guint16 fid;
    guint idx;

    dissector_handle_t h;

    if (tvb_captured_length(tvb) >= 2 && (h = dissector_get_uint_handle(pn_frame_id_table, tvb_get_ntohs(tvb, 0)))) {
        const char *saved = pinfo->match_string;
        gboolean thrown;

        fid = tvb_get_ntohs(tvb, 0);
        consumed = call_pn_rt_known(tvb, pinfo, tree, data, &thrown);
        pinfo->match_string = thrown ? VRSHARK_VIEW_MALFORMED : lua_view(&view_pn, pinfo, tree);
        call_lua_frame_id(h, fid, tvb, pinfo, tree);
        pinfo->match_string = saved;
        return thrown ? (int)tvb_captured_length(tvb) : consumed;
    }
    consumed = pn_rt_handle ? call_dissector_only(pn_rt_handle, tvb, pinfo, tree, data) : 0;
    if (tvb_captured_length(tvb) < 2)
        return consumed;
    fid = tvb_get_ntohs(tvb, 0);
    if (fid < PN_CANDIDATE_FIRST || fid > PN_CANDIDATE_LAST || pinfo->fd->visited)
        return consumed;
    idx = fid - PN_CANDIDATE_FIRST;
    if (pn_tries[idx] >= VRSHARK_PN_CANDIDATE_TRIES && !vrshark_flag_pn_pending)
        return consumed;
    if (!dissector_try_string_with_data(pn_hook_table, VRSHARK_PN_HOOK_CANDIDATE, tvb, pinfo, tree, FALSE, NULL) &&
        pn_tries[idx] < VRSHARK_PN_CANDIDATE_TRIES)
        pn_tries[idx]++;
    return consumed;
}

static int
dissect_pn_cyclic(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree, void *data)
{
    int consumed;

    tcp_ends_deliver(tvb, pinfo, tree);
    consumed = pn_cyclic(tvb, pinfo, tree, data);
    clock_tick(tvb, pinfo, tree);
    return consumed;
}

/* ---- Owning EtherType 0x8892 ----------------------------------------------- */

/* Plugins are handed off in an order that depends on the folders they sit in
 * (personal, global, WIRESHARK_PLUGIN_DIR): Wireshark's own profinet plugin
 * may be handed off after this one and put PN-RT back on EtherType 0x8892,
 * and then no cyclic frame would reach the Lua decoders. Every hand-off has
 * run when a file starts, so the entry is checked there (and at hand-off):
 * PN-RT, or nothing, is replaced by the front end again (PN-RT becomes the
 * dissector it wraps); anything else is somebody's own wrapper, left alone
 * and said once on stderr and as expert info on each Connect whose cyclic
 * frames it costs. */
static const char *pn_taken_by;     /* the dissector holding 0x8892, or NULL */

static void
own_pn_rt(void)
{
    static gboolean said;
    dissector_handle_t cur = dissector_get_uint_handle(find_dissector_table("ethertype"), ETHERTYPE_PNRT);
    dissector_handle_t pn_rt = find_dissector("pn_rt");

    pn_taken_by = NULL;
    if (cur == pn_cyclic_handle)
        return;
    if (cur == NULL || cur == pn_rt) {
        if (pn_rt)
            pn_rt_handle = pn_rt;
        dissector_add_uint("ethertype", ETHERTYPE_PNRT, pn_cyclic_handle);
        return;
    }
    /* (the name the Lua side can give too: the protocol's short name) */
    pn_taken_by = dissector_handle_get_protocol_short_name(cur);
    if (!pn_taken_by)
        pn_taken_by = dissector_handle_get_dissector_name(cur);
    if (!pn_taken_by)
        pn_taken_by = "another dissector";
    if (!said) {
        fprintf(stderr, "vrshark: EtherType 0x8892 (PROFINET RT) is taken by \"%s\": MC-MB2-PN and EC-Link "
                "over PROFINET are not decoded; remove or disable that plugin\n", pn_taken_by);
        said = TRUE;
    }
}

/* UDP 34964 (PNIO-CM): empty, or still ours, at each file start; anything
 * else there is said once (no Connect is then read: layouts come from the
 * layout table and the cyclic frames). */
static void
own_pn_cm(void)
{
    static gboolean said;
    dissector_handle_t cur = dissector_get_uint_handle(find_dissector_table("udp.port"), UDP_PORT_PNIO_CM);

    if (cur == pn_cm_handle)
        return;
    if (cur == NULL) {
        dissector_add_uint("udp.port", UDP_PORT_PNIO_CM, pn_cm_handle);
        return;
    }
    if (!said) {
        const char *name = dissector_handle_get_protocol_short_name(cur);

        fprintf(stderr, "vrshark: UDP port 34964 (PNIO-CM) is taken by \"%s\": PROFINET Connects are not "
                "read; layouts come from the layout table and the cyclic frames\n", name ? name : "another dissector");
        said = TRUE;
    }
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

/* A Connect request or response (opnum 0), whole or one fragment of it (the
 * Lua side puts the fragments of a large one together). */
static gboolean
is_connect(tvbuff_t *tvb)
{
    guint encoding;

    if (tvb_captured_length(tvb) < DCERPC_DG_HEADER_LEN)
        return FALSE;
    /* (the last fragment's body may be short) */
    if (!(tvb_get_uint8(tvb, 2) & DCERPC_DG_FLAGS1_FRAG) && tvb_captured_length(tvb) < PNIO_CONNECT_MIN_LEN)
        return FALSE;
    encoding = (tvb_get_uint8(tvb, 4) & DCERPC_DG_DREP_LITTLE) ? ENC_LITTLE_ENDIAN : ENC_BIG_ENDIAN;
    return tvb_get_uint16(tvb, DCERPC_DG_OPNUM_OFF, encoding) == PNIO_CM_CONNECT;
}

/* Expected submodule blocks (type 0x0104) of the Connect requests the
 * carrier returned 0 for: no system of ours (it keeps the same set). While
 * it holds no AR learned from a request (hook "response" absent), a request
 * with the same blocks would only be looked up in that set there, so it is
 * not handed over: a controller connects the same foreign devices again and
 * again. Per file. */
typedef struct {
    guint len;
    const guint8 *bytes;
} pn_subs_key_t;

static wmem_map_t *pn_foreign_subs;

#define PNIO_BLOCK_EXPECTED_SUBMODULES 0x0104
/* the PNIO args after the DCE/RPC header: ArgsMaximum/status (4),
 * ArgsLength (4), MaximumCount, Offset and ActualCount (4 each) */
#define PNIO_ARGS_LENGTH_OFF    (DCERPC_DG_HEADER_LEN + 4)
#define PNIO_BLOCKS_OFF         (DCERPC_DG_HEADER_LEN + 20)

static guint
pn_subs_hash(gconstpointer k)
{
    const pn_subs_key_t *key = (const pn_subs_key_t *)k;
    guint h = 2166136261u;
    guint i;

    for (i = 0; i < key->len; i++)
        h = (h ^ key->bytes[i]) * 16777619u;
    return h;
}

static gboolean
pn_subs_equal(gconstpointer a, gconstpointer b)
{
    const pn_subs_key_t *x = (const pn_subs_key_t *)a, *y = (const pn_subs_key_t *)b;

    return x->len == y->len && memcmp(x->bytes, y->bytes, x->len) == 0;
}

/* The expected submodule blocks of an unfragmented Connect request, one
 * after the other, as the carrier reads them (vrshark_pnio.lua
 * connect_blocks(): each block that ends inside the datagram, up to
 * ArgsLength); FALSE when it has none. The bytes are the packet's. */
static gboolean
pn_subs_of(tvbuff_t *tvb, packet_info *pinfo, pn_subs_key_t *key)
{
    guint tlen = tvb_captured_length(tvb);
    guint encoding = (tvb_get_uint8(tvb, 4) & DCERPC_DG_DREP_LITTLE) ? ENC_LITTLE_ENDIAN : ENC_BIG_ENDIAN;
    guint64 stop;
    guint off = PNIO_BLOCKS_OFF;
    wmem_array_t *subs;

    if (tlen < PNIO_CONNECT_MIN_LEN)
        return FALSE;
    stop = MIN((guint64)PNIO_BLOCKS_OFF + tvb_get_uint32(tvb, PNIO_ARGS_LENGTH_OFF, encoding), tlen);
    subs = wmem_array_new(pinfo->pool, 1);
    while (off + 6 <= stop) {
        guint type = tvb_get_ntohs(tvb, off);
        guint end = off + 4 + tvb_get_ntohs(tvb, off + 2);

        if (type == PNIO_BLOCK_EXPECTED_SUBMODULES && end <= tlen)
            wmem_array_append(subs, tvb_get_ptr(tvb, off, end - off), end - off);
        off = end;
    }
    key->len = wmem_array_get_count(subs);
    key->bytes = (const guint8 *)wmem_array_get_raw(subs);
    return key->len > 0;
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
pn_cm(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree, void *data)
{
    heur_dtbl_entry_t *hdtbl_entry;
    pn_subs_key_t subs;
    gboolean keyed = FALSE;
    gboolean cut = FALSE;

    /* A DCE/RPC datagram the capture cut (snaplen): the carrier says so
     * first (a cut Connect's layout cannot be read), as DCE/RPC may throw
     * on it; it is handed over once. */
    if (tvb_captured_length(tvb) < tvb_reported_length(tvb) && tvb_captured_length(tvb) >= 2 &&
        tvb_get_uint8(tvb, 0) == DCERPC_DG_VERSION && dissector_get_string_handle(pn_hook_table, VRSHARK_PN_HOOK_CONNECT)) {
        dissector_try_string_with_data(pn_hook_table, VRSHARK_PN_HOOK_CONNECT, tvb, pinfo, tree, FALSE, NULL);
        cut = TRUE;
    }
    if (!is_dcerpc_dg(tvb))
        return 0;
    if (!dissector_try_heuristic(udp_heur_list, tvb, pinfo, tree, &hdtbl_entry, data))
        return 0;
    if (!cut && is_connect(tvb) && dissector_get_string_handle(pn_hook_table, VRSHARK_PN_HOOK_CONNECT)) {
        if (!pinfo->fd->visited && tvb_get_uint8(tvb, 1) == DCERPC_DG_REQUEST)
            learn_controller_port(pinfo);
        if (pn_taken_by)
            expert_add_info_format(pinfo, proto_tree_add_item(tree, proto_vrshark_pnio, tvb, 0, 0, ENC_NA),
                &ei_pn_taken, "Cyclic frames of this Connect are not decoded: EtherType 0x8892 is taken "
                "by \"%s\", not by vrshark_pnio", pn_taken_by);
        /* A response teaches the carrier something only about an AR it
         * learned from a request, and it says when it holds one (flag
         * VRSHARK_FLAG_PN_RESPONSE): a capture of foreign devices hands it
         * no response, and no request it found foreign before
         * (pn_foreign_subs). On a later pass every response goes to it
         * (what it learned on the first is shown; an AR may have been
         * dropped since). */
        if (!vrshark_flag_pn_response) {
            if (tvb_get_uint8(tvb, 1) == DCERPC_DG_RESPONSE && !pinfo->fd->visited)
                return tvb_captured_length(tvb);
            keyed = !(tvb_get_uint8(tvb, 2) & DCERPC_DG_FLAGS1_FRAG) && pn_subs_of(tvb, pinfo, &subs);
            if (keyed && wmem_map_contains(pn_foreign_subs, &subs))
                return tvb_captured_length(tvb);
        }
        if (dissector_try_string_with_data(pn_hook_table, VRSHARK_PN_HOOK_CONNECT, tvb, pinfo, tree, FALSE, NULL) == 0 && keyed &&
            !pinfo->fd->visited) {
            pn_subs_key_t *kept = wmem_new(wmem_file_scope(), pn_subs_key_t);

            kept->len = subs.len;
            kept->bytes = (const guint8 *)wmem_memdup(wmem_file_scope(), subs.bytes, subs.len);
            wmem_map_insert(pn_foreign_subs, kept, kept);
        }
    }
    return tvb_captured_length(tvb);
}

static int
dissect_pn_cm(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree, void *data)
{
    int consumed;

    tcp_ends_deliver(tvb, pinfo, tree);
    consumed = pn_cm(tvb, pinfo, tree, data);
    clock_tick(tvb, pinfo, tree);
    return consumed;
}

/* ---- Modbus/TCP ----------------------------------------------------------- */

#define MB_ACCEPTED 0x80000000u
#define MB_LIVE     0x40000000u     /* a request shaped like BU evidence was seen */
#define MB_TRIES_MASK 0x0FFFFFFFu
#define MB_TRIED    0               /* proto data key: a frame the decoder refused */
#define MB_MID_ADU  1               /* packet-scope key: bytes mbtcp refused, handed to the decoder */

/* Does [start, start + count) cover the n addresses from first? */
static gboolean
mb_covers(guint start, guint count, guint first, guint n)
{
    return start <= first && start + count >= first + n;
}

/* Is this the whole output image written (Standard or Input + Commands)? */
static gboolean
mb_output_write(guint start, guint count)
{
    return start == VRSHARK_MB_OUTPUT_REG_FIRST &&
           (count == VRSHARK_MB_OUTPUT_COMMANDS_REGS || count == VRSHARK_MB_OUTPUT_REGS);
}

/* Would this request, if the server were a BU, carry the evidence the Lua
 * heuristic accepts a connection on (vrshark/modbus_detect.luam): the whole
 * input image read or the whole output image written, at the addresses of
 * the seam contract (VRSHARK_MB_INPUT_*, VRSHARK_MB_OUTPUT_*)? A connection
 * whose client never asks for one can never be accepted, so its frames need
 * not reach Lua at all: that keeps ordinary Modbus/TCP out of Lua. Every ADU
 * of the buffer is looked at. */
static gboolean
mb_evidence_request(tvbuff_t *tvb)
{
    guint len = tvb_captured_length(tvb);
    guint off = 0;

    while (off + 12 <= len) {
        guint adu = 6 + tvb_get_ntohs(tvb, off + 4);
        guint8 fc = tvb_get_uint8(tvb, off + 7);
        guint start = tvb_get_ntohs(tvb, off + 8), count = tvb_get_ntohs(tvb, off + 10);

        if (adu < 8)
            return FALSE;
        switch (fc) {
        case 2:     /* discrete inputs: the input image as bits */
            if (mb_covers(start, count, VRSHARK_MB_INPUT_BIT_FIRST, VRSHARK_MB_INPUT_BITS))
                return TRUE;
            break;
        case 3:     /* holding registers: the input image */
            if (mb_covers(start, count, VRSHARK_MB_INPUT_HOLDING_FIRST, VRSHARK_MB_INPUT_REGS))
                return TRUE;
            break;
        case 4:     /* input registers: the input image */
            if (mb_covers(start, count, VRSHARK_MB_INPUT_REG_FIRST, VRSHARK_MB_INPUT_REGS))
                return TRUE;
            break;
        case 16:    /* the output image written */
            if (mb_output_write(start, count))
                return TRUE;
            break;
        case 23:    /* read and write: either part */
            if (mb_covers(start, count, VRSHARK_MB_INPUT_HOLDING_FIRST, VRSHARK_MB_INPUT_REGS))
                return TRUE;
            if (off + 16 <= len && mb_output_write(tvb_get_ntohs(tvb, off + 12), tvb_get_ntohs(tvb, off + 14)))
                return TRUE;
            break;
        default:
            break;
        }
        off += adu;
    }
    return FALSE;
}
/* The TCP port of Wireshark's Modbus/TCP dissector (its preference
 * mbtcp.tcp.port, 502 unless set), found when each file starts: mbtcp tells
 * queries from responses by it. */
static guint mb_port;
/* The ports the front end sits on (eclink_modbus.port, a range, and mbtcp's
 * port), each with whether it took the port from mbtcp. */
typedef struct {
    guint port;
    gboolean displaced;
} mb_placed_t;
static GArray *mb_placed;

/* mbtcp.tcp.port is a Decode As preference, which prefs_get_uint_value()
 * does not read: it is the port the tcp.port table gives mbtcp, one other
 * than 502 if there is one (502 keeps it when the preference moves). The
 * Lua side finds it the same way without the C plugin. */
static void
find_mbtcp_port(const gchar *table_name, ftenum_t selector_type, gpointer key, gpointer value,
                gpointer user_data)
{
    guint *found = (guint *)user_data;

    (void)table_name;
    (void)selector_type;
    if (dtbl_entry_get_handle((dtbl_entry_t *)value) == mbtcp_handle && (*found == 0 || *found == 502))
        *found = GPOINTER_TO_UINT(key);
}

/* The front end on one more port (once; 0 is no port). */
static void
place_mb_port(guint32 port, gpointer user_data)
{
    dissector_table_t tcp = (dissector_table_t)user_data;
    dissector_handle_t cur;
    mb_placed_t placed;

    if (port == 0 || port > 65535)
        return;
    cur = dissector_get_uint_handle(tcp, port);
    if (cur == mb_front_handle)
        return;
    placed.port = port;
    placed.displaced = cur == mbtcp_handle;
    dissector_add_uint("tcp.port", port, mb_front_handle);
    g_array_append_val(mb_placed, placed);
}

/* At each file start: the front end on the BUs' ports. The ports of the last
 * file are given back first (to mbtcp where it had them), so that mbtcp's own
 * port is found in the table as Wireshark set it; then the front end sits on
 * every port of eclink_modbus.port (a range, 502 by default) and on mbtcp's
 * port: either setting adds a port, neither takes one away (the Lua side does
 * the same without this plugin). Only with the Lua decoders (their
 * preferences exist). */
static void
own_mb_port(void)
{
    dissector_table_t tcp = find_dissector_table("tcp.port");
    range_t *ports;
    guint i;

    if (!mb_placed)
        mb_placed = g_array_new(FALSE, FALSE, sizeof(mb_placed_t));
    for (i = 0; i < mb_placed->len; i++) {
        mb_placed_t *placed = &g_array_index(mb_placed, mb_placed_t, i);

        if (dissector_get_uint_handle(tcp, placed->port) != mb_front_handle)
            continue;
        if (placed->displaced)
            dissector_add_uint("tcp.port", placed->port, mbtcp_handle);
        else
            dissector_delete_uint("tcp.port", placed->port, mb_front_handle);
    }
    g_array_set_size(mb_placed, 0);
    mb_port = 0;
    dissector_table_foreach("tcp.port", find_mbtcp_port, &mb_port);
    if (!prefs_find_module("eclink_modbus"))
        return;
    ports = prefs_get_range_value("eclink_modbus", "port");
    if (ports)
        range_foreach(ports, place_mb_port, tcp);
    place_mb_port(mb_port, tcp);
}

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

/* Is `name` a listed server: in the list the Lua side said
 * (vrshark_mb_servers), or where it cannot say it, an entry of the hook
 * table? */
static gboolean
mb_server_named(const char *name)
{
    if (vrshark_mb_servers)
        return g_hash_table_contains(vrshark_mb_servers, name);
    return dissector_get_string_handle(mb_hook_table, name) != NULL;
}

/* Is the server of this frame (the destination of a request: to the port
 * the front end was called for) one the user listed? Its name in the list:
 * "server ADDR:PORT", or "server ADDR" for every port. */
static gboolean
mb_listed(packet_info *pinfo, guint32 server_port)
{
    const address *server;
    guint32 port;
    char *addr, *key;
    gboolean found;

    if (!mb_hooks.server || (vrshark_mb_servers && g_hash_table_size(vrshark_mb_servers) == 0))
        return FALSE;
    if (pinfo->destport == server_port) {
        server = &pinfo->dst;
        port = pinfo->destport;
    } else {
        server = &pinfo->src;
        port = pinfo->srcport;
    }
    addr = address_to_str(pinfo->pool, server);
    key = wmem_strdup_printf(pinfo->pool, VRSHARK_MB_SERVER_PREFIX "%s:%u", addr, port);
    found = mb_server_named(key);
    if (!found) {
        key = wmem_strdup_printf(pinfo->pool, VRSHARK_MB_SERVER_PREFIX "%s", addr);
        found = mb_server_named(key);
    }
    return found;
}

/* The Lua decoder registered as v->hook ("always", "heuristic", "server"), with
 * pinfo->match_string what it is to add (lua_view; everything while the
 * connection is still a candidate: `full`). Its protocol joins the layer
 * list, as when it wraps mbtcp itself. */
static int
call_mb_decoder(lua_view_t *v, gboolean full, tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree)
{
    const char *saved = pinfo->match_string;
    dissector_handle_t h = v == &view_mb_always ? mb_hooks.always : v == &view_mb_server ? mb_hooks.server
                           : mb_hooks.heuristic;
    int ret;

    pinfo->match_string = full ? v->hook : lua_view(v, pinfo, tree);
    ret = call_lua_decoder(h, tvb, pinfo, tree);
    pinfo->match_string = saved;
    return ret;
}

/* mbtcp classifies an ADU as query or response by its own TCP port
 * preference (mbtcp.tcp.port). On another port it is shown the server's port
 * as that one while it runs, so that one setting (eclink_modbus.port or
 * mbtcp.tcp.port) is enough; on its own port it is left alone. */
static int
call_mbtcp(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree, void *data)
{
    guint32 bu_port = pinfo->match_uint;
    guint32 srcport = pinfo->srcport, destport = pinfo->destport;
    gboolean moved = mb_port != 0 && bu_port != mb_port && (srcport == bu_port) != (destport == bu_port) &&
                     srcport != mb_port && destport != mb_port;
    volatile int consumed = 0;

    if (!moved)
        return call_dissector_only(mbtcp_handle, tvb, pinfo, tree, data);
    if (destport == bu_port)
        pinfo->destport = mb_port;
    else
        pinfo->srcport = mb_port;
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

/* A TCP connection to a Modbus server, as eclink_modbus.lua keys it (client
 * and server address and port): the state of mb_state. Looked up on every
 * frame of a server port, so it is hashed here from the address bytes and
 * ports; a conversation lookup (find_conversation_pinfo: two hashes of both
 * addresses on a response) was half of what the front end cost a Modbus/TCP
 * connection that is no BU's (docs/quality.md, foreign traffic). A new
 * connection on the same addresses and ports continues the state of the
 * one before, as on the Lua side. */
typedef struct {
    address client, server;
    guint32 client_port, server_port;
} mb_conn_key_t;

static guint
mb_conn_hash(gconstpointer k)
{
    const mb_conn_key_t *key = (const mb_conn_key_t *)k;
    const guint8 *b;
    guint h = 2166136261u ^ (key->client_port << 16) ^ key->server_port;
    int i;

    b = (const guint8 *)key->client.data;
    for (i = 0; i < key->client.len; i++)
        h = (h ^ b[i]) * 16777619u;
    b = (const guint8 *)key->server.data;
    for (i = 0; i < key->server.len; i++)
        h = (h ^ b[i]) * 16777619u;
    return h;
}

static gboolean
mb_conn_equal(gconstpointer a, gconstpointer b)
{
    const mb_conn_key_t *x = (const mb_conn_key_t *)a, *y = (const mb_conn_key_t *)b;

    return x->client_port == y->client_port && x->server_port == y->server_port &&
           addresses_equal(&x->client, &y->client) && addresses_equal(&x->server, &y->server);
}

/* The key of this frame's connection (pointing into pinfo): the server is the
 * end on server_port; with that port at both ends, the lower address. */
static void
mb_conn_key(packet_info *pinfo, guint32 server_port, mb_conn_key_t *key)
{
    gboolean to_server = pinfo->destport == server_port &&
                         (pinfo->srcport != server_port || cmp_address(&pinfo->dst, &pinfo->src) <= 0);

    key->client = to_server ? pinfo->src : pinfo->dst;
    key->server = to_server ? pinfo->dst : pinfo->src;
    key->client_port = to_server ? pinfo->srcport : pinfo->destport;
    key->server_port = server_port;
}

/* The state of a connection, its key copied the first time. */
static void
mb_conn_store(const mb_conn_key_t *conn, guint32 state)
{
    mb_conn_key_t *key;

    if (wmem_map_contains(mb_state, conn)) {
        wmem_map_insert(mb_state, conn, GUINT_TO_POINTER(state));
        return;
    }
    key = wmem_new(wmem_file_scope(), mb_conn_key_t);
    copy_address_wmem(wmem_file_scope(), &key->client, &conn->client);
    copy_address_wmem(wmem_file_scope(), &key->server, &conn->server);
    key->client_port = conn->client_port;
    key->server_port = conn->server_port;
    wmem_map_insert(mb_state, key, GUINT_TO_POINTER(state));
}

/* Bytes mbtcp refused, on a connection the decoder decodes (else they stay
 * TCP's), go to the decoder once (TCP offers them to the server's port and
 * then to the lower port, the same port): the head of a response alone in
 * its segment, for which it asks TCP for the rest (mbtcp never would), or
 * data from inside an ADU (segments out of order, or not captured), which
 * it notes. */
static int
mb_refused(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree, guint32 server_port)
{
    mb_conn_key_t conn;
    lua_view_t *v = mb_hooks.always ? &view_mb_always : mb_listed(pinfo, server_port) ? &view_mb_server : NULL;

    if (!v && mb_hooks.heuristic && pinfo->ptype == PT_TCP) {
        mb_conn_key(pinfo, server_port, &conn);
        if (GPOINTER_TO_UINT(wmem_map_lookup(mb_state, &conn)) & MB_ACCEPTED)
            v = &view_mb_heuristic;
    }
    if (!v || p_get_proto_data(pinfo->pool, pinfo, proto_vrshark_mbtcp, MB_MID_ADU))
        return 0;
    p_add_proto_data(pinfo->pool, pinfo, proto_vrshark_mbtcp, MB_MID_ADU, GUINT_TO_POINTER(1));
    pinfo->desegment_len = 0;
    call_mb_decoder(v, FALSE, tvb, pinfo, tree);
    return pinfo->desegment_len ? (int)tvb_captured_length(tvb) : 0;
}

static int
mbtcp_front(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree, void *data)
{
    mb_conn_key_t conn;
    guint32 state;
    int consumed;
    guint32 server_port = pinfo->match_uint;

    leave_layer_list(pinfo);
    /* mbtcp may use TCP desegmentation as if TCP had called it directly */
    if (pinfo->can_desegment > 0)
        pinfo->can_desegment++;
    consumed = call_mbtcp(tvb, pinfo, tree, data);
    if (consumed < 0)
        return consumed;
    mb_read_hooks();
    if (consumed == 0)
        return mb_refused(tvb, pinfo, tree, server_port);
    if (mb_hooks.always) {
        call_mb_decoder(&view_mb_always, FALSE, tvb, pinfo, tree);
        return consumed;
    }
    if (mb_listed(pinfo, server_port)) {
        call_mb_decoder(&view_mb_server, FALSE, tvb, pinfo, tree);
        return consumed;
    }
    if (!mb_hooks.heuristic || pinfo->ptype != PT_TCP)
        return consumed;
    mb_conn_key(pinfo, server_port, &conn);
    state = GPOINTER_TO_UINT(wmem_map_lookup(mb_state, &conn));
    if (state & MB_ACCEPTED) {
        call_mb_decoder(&view_mb_heuristic, FALSE, tvb, pinfo, tree);
        return consumed;
    }
    /* a candidate: later passes keep the first pass's refusals; the frames
     * the decoder looked at then go to it again for its notes (lua_view) */
    if (pinfo->fd->visited) {
        if (p_get_proto_data(wmem_file_scope(), pinfo, proto_vrshark_mbtcp, MB_TRIED))
            call_mb_decoder(&view_mb_heuristic, FALSE, tvb, pinfo, tree);
        return consumed;
    }
    if ((state & MB_TRIES_MASK) >= VRSHARK_MB_CANDIDATE_TRIES)
        return consumed;
    if (!(state & MB_LIVE)) {
        if (pinfo->destport != server_port || !mb_evidence_request(tvb))
            return consumed;
        state |= MB_LIVE;
    }
    if (call_mb_decoder(&view_mb_heuristic, TRUE, tvb, pinfo, tree)) {
        state = MB_ACCEPTED;
    } else {
        state++;
        p_add_proto_data(wmem_file_scope(), pinfo, proto_vrshark_mbtcp, MB_TRIED, GUINT_TO_POINTER(1));
    }
    mb_conn_store(&conn, state);
    return consumed;
}

static int
dissect_mbtcp_front(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree, void *data)
{
    int consumed;

    tcp_ends_deliver(tvb, pinfo, tree);
    consumed = mbtcp_front(tvb, pinfo, tree, data);
    clock_tick(tvb, pinfo, tree);
    return consumed;
}

/* ---- A BU's server on a TCP port nobody reads as Modbus/TCP ---------------- */

/* TCP offers the segments no port dissector took to its heuristics. A
 * request whose MBAP headers fill the segment exactly and that carries a
 * BU's evidence (mb_evidence_request) goes to Lua hook "port_hint", which
 * notes the setting that decodes its server (eclink_modbus.lua port_hint,
 * the same check again); anything else never enters Lua. */
static gboolean
mb_exact_adus(tvbuff_t *tvb)
{
    guint len = tvb_captured_length(tvb), off = 0;

    if (len < 12 || len > 4096 || tvb_reported_length(tvb) != len)
        return FALSE;
    while (off < len) {
        guint adu;

        if (off + 12 > len || tvb_get_ntohs(tvb, off + 2) != 0)
            return FALSE;
        adu = 6 + tvb_get_ntohs(tvb, off + 4);
        if (adu < 12 || off + adu > len)
            return FALSE;
        off += adu;
    }
    return TRUE;
}

static dissector_table_t tcp_port_table;

static eglink_heur_bool_t
dissect_mb_port_hint(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree, void *data _U_)
{
    /* (a port some dissector sits on had its turn, or has it next: TCP's
     * "try heuristic sub-dissectors first") */
    if (!mb_exact_adus(tvb) || !mb_evidence_request(tvb) ||
        dissector_get_uint_handle(tcp_port_table, pinfo->destport) ||
        !dissector_get_string_handle(mb_hook_table, VRSHARK_MB_HOOK_PORT_HINT))
        return FALSE;
    /* the note's protocol in the layer list, not the front end's, as
     * without the C plugin */
    leave_layer_list(pinfo);
    return dissector_try_string_with_data(mb_hook_table, VRSHARK_MB_HOOK_PORT_HINT, tvb, pinfo, tree, TRUE, NULL) != 0;
}

/* ---- Registration ----------------------------------------------------------- */

/* What was looked up of the Lua side: protocol ids, their fields, the
 * views made of them, the -e fields. Analyze > Reload Lua Plugins
 * deregisters the Lua protocols and fields and registers them anew under
 * other ids (the old ones then name nothing: "Unregistered hf!"), and is
 * followed by a new dissection, which starts here. Each file starts here
 * too: nothing of the Lua side is kept from one to the next. */
static void
forget_lua_side(void)
{
    lua_view_t *views[] = { &view_pn, &view_mb_always, &view_mb_heuristic, &view_mb_server };
    guint i;

    for (i = 0; i < G_N_ELEMENTS(views); i++) {
        lua_view_free(views[i]);
        memset(views[i]->ids, 0, sizeof views[i]->ids);
    }
    if (named_fields)
        g_array_free(named_fields, TRUE);
    named_fields = NULL;
    named_other = FALSE;
    mb_hooks.changes = 0;
}

static void
frontends_init(void)
{
    guint i;

    memset(pn_tries, 0, sizeof pn_tries);
    vrshark_clock_reset();
    vrshark_tcp_ends_reset();
    forget_lua_side();
    mb_state = wmem_map_new(wmem_file_scope(), mb_conn_hash, mb_conn_equal);
    pn_foreign_subs = wmem_map_new(wmem_file_scope(), pn_subs_hash, pn_subs_equal);
    for (i = 0; i < pn_learned_ports->len; i++)
        dissector_delete_uint("udp.port", g_array_index(pn_learned_ports, guint32, i), pn_cm_handle);
    g_array_set_size(pn_learned_ports, 0);
    own_pn_rt();
    own_pn_cm();
    own_mb_port();
}

static void
frontends_shutdown(void)
{
    g_array_free(pn_learned_ports, TRUE);
    forget_lua_side();
    if (view_scratch)
        g_array_free(view_scratch, TRUE);
    view_scratch = NULL;
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
    mb_front_handle = register_dissector(VRSHARK_MB_FRONT_NAME, dissect_mbtcp_front, proto_vrshark_mbtcp);

    pn_frame_id_table = register_dissector_table(VRSHARK_PN_FRAME_ID_TABLE,
        "vrshark: PROFINET cyclic FrameIDs decoded in Lua", proto_vrshark_pnio, FT_UINT16, BASE_HEX);
    pn_hook_table = register_dissector_table(VRSHARK_PN_HOOK_TABLE,
        "vrshark: PROFINET candidates and Connects for Lua", proto_vrshark_pnio, FT_STRING,
        FALSE /* case-sensitive */);
    mb_hook_table = register_dissector_table(VRSHARK_MB_HOOK_TABLE,
        "vrshark: Modbus/TCP connections for Lua", proto_vrshark_mbtcp, FT_STRING, FALSE /* case-sensitive */);

    static ei_register_info ei[] = {
        { &ei_pn_taken, { "vrshark_pnio.ethertype_taken", PI_UNDECODED, PI_ERROR,
            "EtherType 0x8892 is taken by another dissector: cyclic frames are not decoded", EXPFILL } },
    };
    expert_register_field_array(expert_register_protocol(proto_vrshark_pnio), ei, array_length(ei));

    pn_learned_ports = g_array_new(FALSE, FALSE, sizeof(guint32));
    full_tree_always = g_getenv(VRSHARK_ENV_FULL_TREE) != NULL;
    vrshark_columns_register();
    register_init_routine(frontends_init);
    register_shutdown_routine(frontends_shutdown);
}

void
proto_reg_handoff_vrshark_frontends(void)
{
    pn_rt_handle = find_dissector_add_dependency("pn_rt", proto_vrshark_pnio);
    mbtcp_handle = find_dissector_add_dependency("mbtcp", proto_vrshark_mbtcp);
    udp_heur_list = find_heur_dissector_list("udp");
    tcp_port_table = find_dissector_table("tcp.port");
    heur_dissector_add("tcp", dissect_mb_port_hint, "EC-Link BU server on a TCP port not read as Modbus/TCP",
                       "vrshark_mbtcp_port_hint", proto_vrshark_mbtcp, HEURISTIC_ENABLE);
    /* taken again when each file starts: own_pn_rt() */
    own_pn_rt();
    dissector_add_uint("udp.port", UDP_PORT_PNIO_CM, pn_cm_handle);
}
