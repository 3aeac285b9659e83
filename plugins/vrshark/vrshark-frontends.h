/* vrshark-frontends.h
 * Transport front ends of the vrshark Lua dissectors (vrshark-frontends.c):
 * the names of the dissector tables and hooks the Lua side registers into.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef VRSHARK_FRONTENDS_H
#define VRSHARK_FRONTENDS_H

/* PROFINET: FrameID (uint 16) -> the Lua decoder of a known cyclic frame. */
#define VRSHARK_PN_FRAME_ID_TABLE   "vrshark.pn.frame_id"
/* PROFINET hooks (string table):
 *   "candidate": unknown FrameIDs of the RT class 1 range, a bounded number
 *                of tries per FrameID (return 0: not ours);
 *   "pending":   present while the Lua side waits for the downlink FrameID
 *                of a device found by its header: candidates are then tried
 *                beyond the bound;
 *   "connect":   PNIO-CM Connect requests and responses (after DCE/RPC). */
#define VRSHARK_PN_HOOK_TABLE       "vrshark.pn.hook"
/* Modbus/TCP (string table): "heuristic" -> the Lua decoder, given the
 * frames of a connection until it accepts one (returns non-zero; a bounded
 * number of tries per connection) and every frame after that; "always" ->
 * the Lua decoder, given every frame. */
#define VRSHARK_MB_HOOK_TABLE       "vrshark.mbtcp.hook"
/* The Modbus/TCP front end: the Lua side puts it on its TCP port. */
#define VRSHARK_MB_FRONT_NAME       "vrshark.mbtcp"

/* Heuristic tries: cyclic frames per FrameID, frames per TCP connection.
 * A Modbus/TCP connection may need up to a second of BU traffic before the
 * Lua heuristic accepts it (PCI moving at the 125 ms cadence): 1024 frames
 * cover that second at a 2 ms poll (request and response). */
#define VRSHARK_PN_CANDIDATE_TRIES  64
#define VRSHARK_MB_CANDIDATE_TRIES  1024

void proto_register_vrshark_frontends(void);
void proto_reg_handoff_vrshark_frontends(void);

#endif /* VRSHARK_FRONTENDS_H */
