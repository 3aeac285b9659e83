/* vrshark-frontends.h
 * Transport front ends of the vrshark Lua dissectors (vrshark-frontends.c):
 * the names and limits shared with the Lua side.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef VRSHARK_FRONTENDS_H
#define VRSHARK_FRONTENDS_H

/* The seam between this plugin and the Lua plugins: every name and limit
 * both sides use, defined here for C and in lua/vrshark/seam.luam for Lua
 * (the same names without "VRSHARK_"); tests/test_seam.py holds the two
 * equal and fails on a literal either side uses in their place. What each
 * one means, who writes and reads it and what is cached: docs/design.md,
 * "The seam between C and Lua". */

/* Dissector tables. FrameID (uint 16) -> the Lua decoder of a known cyclic
 * frame; the hooks by name (string tables); the Modbus/TCP front end, which
 * the Lua side puts on the listed servers' ports. (EG-Link's application
 * data table is EGLINK_DATA_TABLE, packet-eglink.h.) */
#define VRSHARK_PN_FRAME_ID_TABLE   "vrshark.pn.frame_id"
#define VRSHARK_PN_HOOK_TABLE       "vrshark.pn.hook"
#define VRSHARK_MB_HOOK_TABLE       "vrshark.mbtcp.hook"
#define VRSHARK_MB_FRONT_NAME       "vrshark.mbtcp"

/* PROFINET hooks (in VRSHARK_PN_HOOK_TABLE):
 *   candidate  called: unknown FrameIDs of the RT class 1 range, first pass,
 *              VRSHARK_PN_CANDIDATE_TRIES refusals (0 back) per FrameID
 *              (unbounded while flag VRSHARK_FLAG_PN_PENDING is on);
 *   connect    called: PNIO-CM Connect requests and responses (after
 *              DCE/RPC); 0 back for a request of no system of the Lua side
 *              (responses on the first pass while flag
 *              VRSHARK_FLAG_PN_RESPONSE is on). */
#define VRSHARK_PN_HOOK_CANDIDATE   "candidate"
#define VRSHARK_PN_HOOK_CONNECT     "connect"

/* The clock (in VRSHARK_PN_HOOK_TABLE, called by every front end): a frame
 * that otherwise does not reach Lua, on a first pass once its time is past
 * the earliest deadline Lua armed (VRSHARK_FN_CLOCK_DUE), on a later pass
 * when Lua marked it as carrying a finding (VRSHARK_FN_CLOCK_MARK). A
 * stream that stops is said on the first frame after its deadline, any
 * frame (lua/vrshark/deadlines.luam). */
#define VRSHARK_PN_HOOK_CLOCK       "clock"

/* Modbus/TCP hooks (in VRSHARK_MB_HOOK_TABLE):
 *   heuristic  called: the frames of a connection until it accepts one
 *              (non-zero back; VRSHARK_MB_CANDIDATE_TRIES refusals per
 *              connection) and every frame after that;
 *   always     called: every frame;
 *   server     called: the frames of the servers listed through
 *              VRSHARK_FN_SERVERS, present while any is listed;
 *   port_hint  called: a request on a port nobody reads as Modbus/TCP that
 *              asks for a BU's evidence;
 *   tcp_end    called: before a front end's own work on a frame, when the
 *              TCP listener of vrshark-tcpends.c kept a segment that ended
 *              a connection the decoder named (it takes them through
 *              VRSHARK_FN_TCP_ENDS).
 * A listed server is VRSHARK_MB_SERVER_PREFIX "ADDR:PORT", or "ADDR" for
 * every port (a name VRSHARK_FN_SERVERS takes, not a table key). */
#define VRSHARK_MB_HOOK_HEURISTIC   "heuristic"
#define VRSHARK_MB_HOOK_ALWAYS      "always"
#define VRSHARK_MB_HOOK_SERVER      "server"
#define VRSHARK_MB_SERVER_PREFIX    "server "
#define VRSHARK_MB_HOOK_PORT_HINT   "port_hint"
#define VRSHARK_MB_HOOK_TCP_END     "tcp_end"

/* Flags: state of the Lua side that the front ends read on every frame,
 * kept in C (vrshark-flags.c) and set by the Lua side through
 * VRSHARK_FN_FLAG the moment it changes:
 *   pending    the PROFINET carrier waits for a downlink FrameID or an
 *              inference is alive: candidates are tried beyond the bound;
 *   response   the carrier holds an AR learned from a request: Connect
 *              responses are handed over on the first pass too.
 * Both are on until the Lua side first sets them (it asks for every frame
 * it might want). */
#define VRSHARK_FLAG_PN_PENDING     "pn.pending"
#define VRSHARK_FLAG_PN_RESPONSE    "pn.response"

/* The view, in pinfo->match_string (vrshark-frontends.c:lua_view encodes it,
 * seam.luam's view() decodes it): HOOK alone (everything), HOOK
 * VRSHARK_VIEW_QUIET (nothing to add), HOOK VRSHARK_VIEW_SPARSE FLAGS ":" LIST
 * (FLAGS of VRSHARK_VIEW_FLAG_*, LIST the referenced fields joined by
 * VRSHARK_VIEW_LIST_SEP), or VRSHARK_VIEW_MALFORMED (PN-RT threw). HOOK is
 * VRSHARK_VIEW_FRAME_ID or a Modbus hook called with a view. */
#define VRSHARK_VIEW_FRAME_ID       "frame_id"
#define VRSHARK_VIEW_QUIET          ".quiet"
#define VRSHARK_VIEW_SPARSE         ".sparse:"
#define VRSHARK_VIEW_MALFORMED      "frame_id.malformed"
#define VRSHARK_VIEW_FLAG_COLS      "c"
#define VRSHARK_VIEW_FLAG_EXPERTS   "e"
#define VRSHARK_VIEW_FLAG_PROTOS    "p"
#define VRSHARK_VIEW_LIST_SEP       ","

/* Environment: the plugin's own path, for the Lua side's package.loadlib of
 * the column writers (set by vrshark-columns.c); every view the whole tree
 * (read by both sides at load). */
#define VRSHARK_ENV_FRONTENDS_LIB   "VRSHARK_FRONTENDS_LIB"
#define VRSHARK_ENV_FULL_TREE       "VRSHARK_FULL_TREE"

/* The column writers vrshark.so exports (vrshark-columns.c), and the
 * clock's two: the earliest deadline (absolute seconds, as text) and a
 * frame number that carries a finding. */
#define VRSHARK_FN_SET_COLS         "vrshark_lua_set_cols"
#define VRSHARK_FN_APPEND_INFO      "vrshark_lua_append_info"
#define VRSHARK_FN_CLOCK_DUE        "vrshark_lua_clock_due"
#define VRSHARK_FN_CLOCK_MARK       "vrshark_lua_clock_mark"

/* The Lua side's state the front ends read (vrshark-flags.c): a flag
 * (VRSHARK_FLAG_*) on or off; the listed servers, all of them each time
 * (none: no server listed); the entries of VRSHARK_MB_HOOK_TABLE changed
 * (the front end reads them again). */
#define VRSHARK_FN_FLAG             "vrshark_lua_flag"
#define VRSHARK_FN_SERVERS          "vrshark_lua_servers"
#define VRSHARK_FN_MB_HOOKS_CHANGED "vrshark_lua_mb_hooks_changed"

/* The TCP segments that end a named connection (vrshark-tcpends.c): a
 * connection named, the segments kept since the last call. */
#define VRSHARK_FN_TCP_END_WATCH    "vrshark_lua_tcp_end_watch"
#define VRSHARK_FN_TCP_ENDS         "vrshark_lua_tcp_ends"

/* Heuristic tries: cyclic frames per FrameID, frames per TCP connection
 * (the Lua decoders bound their own tries by the same numbers).
 * A Modbus/TCP connection may need up to a second of BU traffic before the
 * Lua heuristic accepts it (PCI moving at the 125 ms cadence): 1024 frames
 * cover that second at a 2 ms poll (request and response). */
#define VRSHARK_PN_CANDIDATE_TRIES  64
#define VRSHARK_MB_CANDIDATE_TRIES  1024

/* A BU's evidence: the Modbus addresses of its images, which a request must
 * read whole (the input image) or write whole (the output image) for the
 * Lua heuristic to accept a connection on it (lua/vrshark/modbus_detect.luam;
 * vrshark-frontends.c:mb_evidence_request, eclink_modbus.lua's full_input and
 * full_output_write). The input image, 64 bytes: VRSHARK_MB_INPUT_REGS input
 * registers from VRSHARK_MB_INPUT_REG_FIRST, or as many holding registers
 * from VRSHARK_MB_INPUT_HOLDING_FIRST, or VRSHARK_MB_INPUT_BITS discrete
 * inputs from VRSHARK_MB_INPUT_BIT_FIRST. The output image: holding
 * registers from VRSHARK_MB_OUTPUT_REG_FIRST, written whole as
 * VRSHARK_MB_OUTPUT_REGS (224 bytes, Standard mode) or
 * VRSHARK_MB_OUTPUT_COMMANDS_REGS (its first 20 bytes, Input + Commands
 * mode); its bits are coils from VRSHARK_MB_OUTPUT_COIL_FIRST. */
#define VRSHARK_MB_INPUT_REG_FIRST      0
#define VRSHARK_MB_INPUT_HOLDING_FIRST  2048
#define VRSHARK_MB_INPUT_REGS           32
#define VRSHARK_MB_INPUT_BIT_FIRST      0
#define VRSHARK_MB_INPUT_BITS           512
#define VRSHARK_MB_OUTPUT_REG_FIRST     0
#define VRSHARK_MB_OUTPUT_REGS          112
#define VRSHARK_MB_OUTPUT_COMMANDS_REGS 10
#define VRSHARK_MB_OUTPUT_COIL_FIRST    0

void proto_register_vrshark_frontends(void);
void proto_reg_handoff_vrshark_frontends(void);

#endif /* VRSHARK_FRONTENDS_H */
