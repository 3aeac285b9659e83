/* packet-eglink.h
 * What the EG-Link dissector learned from one packet, handed to the
 * conversation analysis (eglink-analysis.c): per-BU tracking, command
 * links, VRPO reassembly and the statistics tap.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef PACKET_EGLINK_H
#define PACKET_EGLINK_H

#include <wireshark.h>
#include <epan/packet.h>
#include <epan/prefs.h>

typedef enum {
    EGLINK_TYPE_VRPI,
    EGLINK_TYPE_VRPO,
    EGLINK_TYPE_VRCI,
    EGLINK_TYPE_VRCO,
    EGLINK_TYPE_VRAI,
    EGLINK_TYPE_VRAO,
    EGLINK_TYPE_UNKNOWN     /* "VR??" that TS-0006 does not define */
} eglink_type_t;

/* Header length: 4-byte ID + 12-byte header; the CRC trails the payload. */
#define EGLINK_HEADER_LEN   16
#define EGLINK_CRC_LEN      4
#define EGLINK_VRPO_FRAGMENT_MAX 488

typedef struct {
    eglink_type_t type;
    guint16 revision;
    guint16 origin;
    guint16 serial;
    gboolean has_serial;        /* the header up to the serial is in the packet and the capture */
    guint16 size;               /* header Size field */
    gboolean size_ok;           /* Size matches the UDP payload and the type */
    gboolean crc_ok;            /* CRC matched (the configured variant); TRUE when cut */
    gboolean cut;               /* cut by the capture (snap length): the CRC and some of the
                                 * payload are not in it; analysed as received, from what it holds */

    /* VRPI */
    gboolean has_bu_state;
    guint8 bu_state;

    /* VRCI, VRCO, VRAI, VRAO */
    gboolean has_command_id;
    guint16 command_id;

    /* VRPO: packet number and where its periodic data sits in the tvb */
    gboolean has_packet_number;
    guint16 packet_number;
    int periodic_offset;
    int periodic_len;           /* in the packet: on a cut packet, more than the capture holds */
} eglink_info_t;

/* Whether a UDP port is one of the input ports of the preference (the BU
 * sends to it; the controller sends to it + 2). */
gboolean eglink_is_input_port(guint32 port);

/* BU state names (TS-0006 4.1.1), defined in packet-eglink.c. */
extern const value_string eglink_bu_state_vals[];

/* eglink-analysis.c: called from proto_register_eglink() with the protocol
 * and its preferences module, so it registers its own fields, expert info,
 * preferences, reassembly table and tap under "eglink". */
void eglink_analysis_register(int proto, module_t *prefs);

/* Called once per dissected EG-Link packet (both passes, with or without a
 * tree) after the packet's own fields; adds the generated analysis fields,
 * expert info, reassembly and tap data to eglink_tree/ti. */
void eglink_analysis_dissect(tvbuff_t *tvb, packet_info *pinfo, proto_tree *eglink_tree,
                             proto_item *eglink_item, const eglink_info_t *info);

/* Application data areas handed to the "eglink.data" dissector table (keyed by
 * these strings), so that a decoder of the machine's own IO list (Lua or C)
 * can decode them without the EG-Link plugin knowing its format:
 *   "vrci"  command data of a VRCI (from the RU), 16 bytes
 *   "vrco"  command data of a VRCO (to the RU), 16 bytes
 *   "vrpo"  periodic data to the RU: a one-packet burst, or a reassembled one
 * The decoder finds the device in pinfo->match_uint: the packet's origin
 * (eglink.origin) in the low 16 bits, the BU origin the analysis knows for it
 * (eglink.analysis.bu_origin, 0: not known) in the high 16 bits. (A Lua
 * Field for these would cost every frame of every protocol: Wireshark builds
 * the frame tree for each once any Lua Field exists.) */
#define EGLINK_DATA_TABLE "eglink.data"
void eglink_data_dissect(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree, const char *area,
                         guint16 origin, guint16 bu_origin);

#endif /* PACKET_EGLINK_H */
