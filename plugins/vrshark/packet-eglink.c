/* packet-eglink.c
 * Routines for VisionRemote EG-Link (VM-110 UDP EG-Link, TS-0006) dissection.
 *
 * Every EG-Link packet is one UDP datagram, all integers little-endian:
 *
 *   0   4  Packet ID   "VR" + P/C/A (periodic, command, acknowledge)
 *                           + I/O (input = BU to machine controller,
 *                                  output = machine controller to BU)
 *   4   2  Revision    0 = the layout decoded here
 *   6   2  Origin      unique ID of the sending BU, 0 from the controller
 *   8   2  Serial      sequential per sender
 *  10   2  Size        payload length (= UDP payload length - 20)
 *  12   4  Spare       0
 *  16   n  Payload     VRPI 46, VRPO 2..490, VRCI/VRCO 22, VRAI/VRAO 2
 * 16+n  4  CRC         CRC-32/MPEG-2 over ID + header + payload
 *
 * Input port 5825 (configurable), output port = input port + 2,
 * multicast 239.255.42.20.  Per-BU conversation analysis, command links,
 * VRPO reassembly and the statistics tap live in eglink-analysis.c.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "eglink-compat.h"

#include <epan/exceptions.h>
#include <epan/expert.h>
#include <epan/prefs.h>
#include <epan/unit_strings.h>
#include <epan/crc32-tvb.h>
#include <wsutil/crc32.h>

#include "packet-eglink.h"

void proto_register_eglink(void);
void proto_reg_handoff_eglink(void);

#define EGLINK_DEFAULT_INPUT_PORTS  "5825"
#define EGLINK_OUTPUT_PORT_OFFSET   2
#define EGLINK_MIN_LEN              (EGLINK_HEADER_LEN + EGLINK_CRC_LEN)

#define EGLINK_VRPI_LEN             46
#define EGLINK_VRPO_MIN_LEN         2
#define EGLINK_VRPO_MAX_LEN         (2 + EGLINK_VRPO_FRAGMENT_MAX)
#define EGLINK_CMD_LEN              22
#define EGLINK_ACK_LEN              2

#define EGLINK_BU_STATE_DISARMED    0x10
#define EGLINK_RU_STATE_STOPPED     4
#define EGLINK_RU_STATE_DISARMED    1
#define EGLINK_LINK_PASSIVE         6
#define EGLINK_JOYSTICK_LIMIT       1000

static int proto_eglink = -1;

static dissector_handle_t eglink_handle;

/* Header */
static int hf_eglink_type = -1;
static int hf_eglink_revision = -1;
static int hf_eglink_origin = -1;
static int hf_eglink_serial = -1;
static int hf_eglink_size = -1;
static int hf_eglink_spare = -1;
static int hf_eglink_payload = -1;
static int hf_eglink_payload_spare = -1;
static int hf_eglink_extra_payload = -1;
static int hf_eglink_unknown_payload = -1;
static int hf_eglink_crc = -1;
static int hf_eglink_crc_status = -1;
/* VRPI */
static int hf_eglink_bu_state = -1;
static int hf_eglink_relays_open = -1;
static int hf_eglink_vlaps = -1;
static int hf_eglink_unarmed_rus = -1;
static int hf_eglink_eg_link_status = -1;
static int hf_eglink_ec_link_status = -1;
static int hf_eglink_c_link_status = -1;
static int hf_eglink_armed_ru = -1;
static int hf_eglink_ru_state = -1;
static int hf_eglink_ru_battery = -1;
static int hf_eglink_ru_rssi = -1;
static int hf_eglink_ru_cable = -1;
static int hf_eglink_ru_docked = -1;
static int hf_eglink_ru_disabled = -1;
static int hf_eglink_joystick[4] = { -1, -1, -1, -1 };
static int hf_eglink_switch[8] = { -1, -1, -1, -1, -1, -1, -1, -1 };
static int hf_eglink_encoder = -1;
static int hf_eglink_encoder_switch = -1;
/* VRPO */
static int hf_eglink_packet_number = -1;
static int hf_eglink_periodic_data = -1;
/* VRCI, VRCO, VRAI, VRAO */
static int hf_eglink_command_id = -1;
static int hf_eglink_command_data = -1;

static gint ett_eglink = -1;
static gint ett_eglink_payload = -1;

static expert_field ei_eglink_too_short = EI_INIT;
static expert_field ei_eglink_size_mismatch = EI_INIT;
static expert_field ei_eglink_size_invalid = EI_INIT;
static expert_field ei_eglink_type_unknown = EI_INIT;
static expert_field ei_eglink_revision_unknown = EI_INIT;
static expert_field ei_eglink_origin_nonzero = EI_INIT;
static expert_field ei_eglink_origin_zero = EI_INIT;
static expert_field ei_eglink_spare_nonzero = EI_INIT;
static expert_field ei_eglink_payload_spare_nonzero = EI_INIT;
static expert_field ei_eglink_crc_bad = EI_INIT;
static expert_field ei_eglink_crc_variant = EI_INIT;
static expert_field ei_eglink_relays_open = EI_INIT;
static expert_field ei_eglink_bu_state_unknown = EI_INIT;
static expert_field ei_eglink_link_status_unknown = EI_INIT;
static expert_field ei_eglink_vlaps_range = EI_INIT;
static expert_field ei_eglink_ru_state_stopped = EI_INIT;
static expert_field ei_eglink_ru_state_unknown = EI_INIT;
static expert_field ei_eglink_link_status_passive = EI_INIT;
static expert_field ei_eglink_ru_state_disarmed = EI_INIT;
static expert_field ei_eglink_ru_battery_range = EI_INIT;
static expert_field ei_eglink_ru_rssi_range = EI_INIT;
static expert_field ei_eglink_flag_invalid = EI_INIT;
static expert_field ei_eglink_ru_disabled_unknown = EI_INIT;
static expert_field ei_eglink_fields_disagree = EI_INIT;
static expert_field ei_eglink_link_status_fault = EI_INIT;
static expert_field ei_eglink_joystick_range = EI_INIT;
static expert_field ei_eglink_unarmed_data = EI_INIT;
static expert_field ei_eglink_cut = EI_INIT;

/* Preferences */
typedef enum {
    EGLINK_CRC_MPEG2,
    EGLINK_CRC_BZIP2,
    EGLINK_CRC_ISO_HDLC,
    EGLINK_CRC_STM32,
    EGLINK_CRC_NUM_VARIANTS
} eglink_crc_variant_t;

typedef enum {
    EGLINK_CRC_LE,
    EGLINK_CRC_BE
} eglink_crc_order_t;

static const enum_val_t eglink_crc_variant_vals[] = {
    { "mpeg2",    "CRC-32/MPEG-2 (TS-0006)",                 EGLINK_CRC_MPEG2 },
    { "bzip2",    "CRC-32/BZIP2",                            EGLINK_CRC_BZIP2 },
    { "iso_hdlc", "CRC-32/ISO-HDLC (Ethernet, zlib)",        EGLINK_CRC_ISO_HDLC },
    { "stm32",    "STM32 hardware CRC (32-bit words)",       EGLINK_CRC_STM32 },
    { NULL, NULL, 0 }
};

static const enum_val_t eglink_crc_order_vals[] = {
    { "le", "Little-endian (TS-0006)", EGLINK_CRC_LE },
    { "be", "Big-endian",              EGLINK_CRC_BE },
    { NULL, NULL, 0 }
};

/* Names as a field engineer reads them in expert info. */
static const char *const eglink_crc_variant_names[EGLINK_CRC_NUM_VARIANTS] = {
    "CRC-32/MPEG-2", "CRC-32/BZIP2", "CRC-32/ISO-HDLC", "STM32 hardware CRC"
};

static range_t *eglink_input_ports;
static range_t *eglink_registered_ports;
static gint eglink_crc_variant = EGLINK_CRC_MPEG2;
static gint eglink_crc_order = EGLINK_CRC_LE;
static eglink_pref_bool_t eglink_heuristic = TRUE;

/* Value strings */
static const value_string eglink_type_descr[] = {
    { EGLINK_TYPE_VRPI, "Periodic Input, BU to controller" },
    { EGLINK_TYPE_VRPO, "Periodic Output, controller to BU" },
    { EGLINK_TYPE_VRCI, "Command Input, BU to controller" },
    { EGLINK_TYPE_VRCO, "Command Output, controller to BU" },
    { EGLINK_TYPE_VRAI, "Acknowledge Input, BU to controller" },
    { EGLINK_TYPE_VRAO, "Acknowledge Output, controller to BU" },
    { EGLINK_TYPE_UNKNOWN, "unknown packet type" },
    { 0, NULL }
};

/* Shared with the analysis and the statistics (packet-eglink.h). */
const value_string eglink_bu_state_vals[] = {
    { 0x00, "Initial" },
    { 0x01, "Stopped" },
    { 0x02, "External link error" },
    { 0x03, "Blocked" },
    { 0x04, "Failed" },
    { 0x10, "Disarmed" },
    { 0x11, "Armed" },
    { 0, NULL }
};

/* Why the ES-Link relays are open, per BU state below Disarmed. */
static const value_string eglink_bu_state_advice[] = {
    { 0x00, "the BU is not fully operative yet" },
    { 0x01, "the armed RU asked the BU to stop" },
    { 0x02, "monitoring found an error on the EC-Link or EG-Link" },
    { 0x03, "contact with the armed RU is lost: switch the RU on and arm it again" },
    { 0x04, "the BU self-test found a fatal internal error" },
    { 0, NULL }
};

static const value_string eglink_link_status_vals[] = {
    { 0, "Unused" },
    { 1, "Operational" },
    { 2, "No link" },
    { 3, "Link error" },
    { 4, "Interface error" },
    { 5, "Data error" },
    { 6, "Passive" },
    { 0, NULL }
};

static const value_string eglink_ru_state_vals[] = {
    { 0, "Initial" },
    { 1, "Disarmed" },
    { 2, "Armed" },
    { 3, "Enabled" },
    { 4, "Stopped" },
    { 0, NULL }
};

static const value_string eglink_ru_cable_vals[] = {
    { 0, "Wireless" },
    { 1, "Cable" },
    { 0, NULL }
};

static const value_string eglink_ru_docked_vals[] = {
    { 0, "Not docked" },
    { 1, "Docked" },
    { 0, NULL }
};

static const value_string eglink_ru_disabled_vals[] = {
    { 0, "Enabled" },
    { 1, "Disabled (tilted)" },
    { 2, "Disabled (inactivity)" },
    { 3, "Disabled (other cause)" },
    { 0, NULL }
};

static const value_string eglink_encoder_switch_vals[] = {
    { 0, "Released" },
    { 1, "Pushed" },
    { 0, NULL }
};

static const true_false_string tfs_eglink_relays = { "Open", "Closed" };

/* "87 %": a space before the unit, as everywhere in vrshark (Wireshark's
 * units_percent has none). */
static const unit_name_string eglink_units_percent = { " %", NULL };

/* Type from the packet ID; "VR" already checked. */
static eglink_type_t
eglink_type_from_id(guint8 kind, guint8 dir)
{
    if (dir == 'I') {
        switch (kind) {
        case 'P': return EGLINK_TYPE_VRPI;
        case 'C': return EGLINK_TYPE_VRCI;
        case 'A': return EGLINK_TYPE_VRAI;
        default: break;
        }
    } else if (dir == 'O') {
        switch (kind) {
        case 'P': return EGLINK_TYPE_VRPO;
        case 'C': return EGLINK_TYPE_VRCO;
        case 'A': return EGLINK_TYPE_VRAO;
        default: break;
        }
    }
    return EGLINK_TYPE_UNKNOWN;
}

static gboolean
eglink_is_input(eglink_type_t type)
{
    return type == EGLINK_TYPE_VRPI || type == EGLINK_TYPE_VRCI || type == EGLINK_TYPE_VRAI;
}

/*
 * CRC over the first len bytes in one of the variants.  MPEG-2, BZIP2 and
 * ISO-HDLC come from Wireshark's CRC library.  An STM32 CRC unit fed 32-bit
 * words read from little-endian memory shifts each word in most significant
 * byte first: that is CRC-32/MPEG-2 over the bytes of every 4-byte group in
 * reverse order, a trailing partial word padded with zero bytes.
 */
static guint32
eglink_crc_compute(tvbuff_t *tvb, packet_info *pinfo, guint len, eglink_crc_variant_t variant)
{
    switch (variant) {
    case EGLINK_CRC_BZIP2:
        return ~crc32_mpeg2_tvb_offset(tvb, 0, len);
    case EGLINK_CRC_ISO_HDLC:
        return crc32_ccitt_tvb_offset(tvb, 0, len);
    case EGLINK_CRC_STM32: {
        guint padded = (len + 3) & ~3u;
        guint8 *words = (guint8 *)wmem_alloc0(pinfo->pool, padded);
        guint i;

        tvb_memcpy(tvb, words, 0, len);
        for (i = 0; i < padded; i += 4) {
            guint8 b0 = words[i], b1 = words[i + 1];
            words[i] = words[i + 3];
            words[i + 1] = words[i + 2];
            words[i + 2] = b1;
            words[i + 3] = b0;
        }
        return crc32_mpeg2_seed(words, padded, 0xFFFFFFFFU);
    }
    case EGLINK_CRC_MPEG2:
    default:
        return crc32_mpeg2_tvb_offset(tvb, 0, len);
    }
}

/* Decoding state of one packet: payload bounds for "decode what fits". */
typedef struct {
    tvbuff_t *tvb;
    packet_info *pinfo;
    proto_tree *tree;
    int base;           /* payload offset in tvb */
    int len;            /* payload bytes actually present (UDP length - 20) */
    int cap;            /* ... of which the capture holds these (less when cut by the snap length) */
    gboolean undefined; /* an undefined or out-of-range value was found */
    gboolean untrusted; /* its CRC fits no variant: its values are not judged */
} eglink_payload_t;

/* Adds an unsigned payload field if it fits; FALSE (and *value 0) if not. */
static gboolean
eglink_add_uint(eglink_payload_t *p, int hf, int off, int len, guint32 *value, proto_item **item)
{
    proto_item *ti;

    *value = 0;
    if (item)
        *item = NULL;
    if (off + len > p->cap)
        return FALSE;
    ti = proto_tree_add_item_ret_uint(p->tree, hf, p->tvb, p->base + off, len, ENC_LITTLE_ENDIAN, value);
    if (item)
        *item = ti;
    return TRUE;
}

static gboolean
eglink_add_int(eglink_payload_t *p, int hf, int off, int len, gint32 *value, proto_item **item)
{
    *value = 0;
    *item = NULL;
    if (off + len > p->cap)
        return FALSE;
    *item = proto_tree_add_item_ret_int(p->tree, hf, p->tvb, p->base + off, len, ENC_LITTLE_ENDIAN, value);
    return TRUE;
}

/* Adds a byte block (spare, data) with whatever of it is present and captured. */
static int
eglink_add_bytes(eglink_payload_t *p, int hf, int off, int len, proto_item **item)
{
    if (item)
        *item = NULL;
    if (off >= p->cap)
        return 0;
    if (off + len > p->cap)
        len = p->cap - off;
    if (len <= 0)
        return 0;
    if (item)
        *item = proto_tree_add_item(p->tree, hf, p->tvb, p->base + off, len, ENC_NA);
    else
        proto_tree_add_item(p->tree, hf, p->tvb, p->base + off, len, ENC_NA);
    return len;
}

/* A finding on a payload value; none in a packet whose CRC fits no variant,
 * whose values are its corrupted bytes (its CRC finding says so, once).
 * TRUE when it was added. */
static gboolean
eglink_value_finding(eglink_payload_t *p, proto_item *ti, expert_field *ei, const char *format, ...)
    G_GNUC_PRINTF(4, 5);

static gboolean
eglink_value_finding(eglink_payload_t *p, proto_item *ti, expert_field *ei, const char *format, ...)
{
    va_list ap;
    char *text;

    if (p->untrusted)
        return FALSE;
    va_start(ap, format);
    text = wmem_strdup_vprintf(p->pinfo->pool, format, ap);
    va_end(ap);
    expert_add_info_format(p->pinfo, ti, ei, "%s", text);
    return TRUE;
}

static void
eglink_check_payload_spare(eglink_payload_t *p, int off, int len)
{
    proto_item *ti;
    int present = eglink_add_bytes(p, hf_eglink_payload_spare, off, len, &ti);
    int i;

    for (i = 0; i < present; i++) {
        if (tvb_get_uint8(p->tvb, p->base + off + i) != 0) {
            eglink_value_finding(p, ti, &ei_eglink_payload_spare_nonzero,
                "Payload spare bytes are not 0: reserved for future use, the sender "
                "may use a newer layout than TS-0006");
            break;
        }
    }
}

/* An undefined or out-of-range value: an error in the Protocol group (the
 * "one voice" table of docs/findings.md), and the Info tag [undefined]. */
#define eglink_undefined(p, ti, ei, ...) \
    ((p)->undefined |= eglink_value_finding((p), (ti), (ei), __VA_ARGS__))

/* A value a value_string does not name reads "Unknown (0x42)", in the tree as
 * everywhere else (Wireshark would print a decimal field as "Unknown (66)"). */
static const char *
eglink_value_name(packet_info *pinfo, guint32 value, const value_string *vals)
{
    const char *name = try_val_to_str(value, vals);

    return name ? name : wmem_strdup_printf(pinfo->pool, "Unknown (0x%02x)", value);
}

static void
eglink_show_unknown(proto_item *ti, int hf, guint32 value)
{
    proto_item_set_text(ti, "%s: Unknown (0x%02x)", proto_registrar_get_name(hf), value);
}

/* A 0/1 field (cable, docked, encoder switch) with its value names. */
static void
eglink_check_flag(eglink_payload_t *p, proto_item *ti, int hf, const char *name, guint32 value)
{
    if (value <= 1)
        return;
    eglink_show_unknown(ti, hf, value);
    eglink_undefined(p, ti, &ei_eglink_flag_invalid,
        "%s Unknown (0x%02x): only 0 and 1 are defined", name, value);
}

static void
eglink_check_link_status(eglink_payload_t *p, proto_item *ti, int hf, const char *name, guint32 value)
{
    if (try_val_to_str(value, eglink_link_status_vals))
        return;
    eglink_show_unknown(ti, hf, value);
    eglink_undefined(p, ti, &ei_eglink_link_status_unknown,
        "%s Unknown (0x%02x): defined are 0..6", name, value);
}

/* TS-0006 4.1.2: Passive (link not in use) is reported on the C-Link only,
 * and only when no remote is armed. i: 0 EG-Link, 1 EC-Link, 2 C-Link. */
static void
eglink_check_passive(eglink_payload_t *p, proto_item *ti, int i, guint32 value, gboolean have_armed,
                     guint32 armed_ru)
{
    static const char *const names[] = { "EG-Link", "EC-Link", "C-Link" };

    if (!ti || value != EGLINK_LINK_PASSIVE)
        return;
    if (i != 2)
        eglink_value_finding(p, ti, &ei_eglink_link_status_passive,
            "%s status Passive: only the C-Link reports Passive", names[i]);
    else if (have_armed && armed_ru != 0)
        eglink_value_finding(p, ti, &ei_eglink_link_status_passive,
            "C-Link status Passive while RU 0x%04x is armed: Passive only when no remote is armed",
            armed_ru);
}

/* TS-0006 4.1.2: what a link status 2..5 says of a link in use (0 Unused
 * and 6 Passive say it is not in use). */
static const value_string eglink_link_fault_vals[] = {
    { 2, "the link is not operating: no valid data has been received" },
    { 3, "a configuration error keeps the link from operating" },
    { 4, "the link's interface module reports an error" },
    { 5, "the link is up, but the data exchanged is in error" },
    { 0, NULL }
};

static void
eglink_check_link_fault(eglink_payload_t *p, proto_item *ti, const char *name, guint32 value)
{
    const char *why = try_val_to_str(value, eglink_link_fault_vals);

    if (why)
        eglink_value_finding(p, ti, &ei_eglink_link_status_fault, "%s %s (%u): %s", name,
            val_to_str_const(value, eglink_link_status_vals, "Unknown"), value, why);
}

/* The VRPI fields one finding compares; have_* FALSE where the capture does
 * not hold the field (nothing is judged from it then). */
typedef struct {
    guint32 bu_state, ec_link, armed_ru, ru_state, ru_disabled;
    gboolean have_ec_link, have_armed, have_ru_state, have_ru_disabled;
    proto_item *bu_ti, *ec_ti, *ru_ti, *disabled_ti;
} eglink_vrpi_fields_t;

#define EGLINK_BU_STATE_INITIAL      0x00
#define EGLINK_BU_STATE_STOPPED      0x01
#define EGLINK_BU_STATE_LINK_ERROR   0x02
#define EGLINK_BU_STATE_ARMED        0x11
#define EGLINK_RU_STATE_INITIAL      0
#define EGLINK_RU_STATE_ARMED        2
#define EGLINK_RU_STATE_ENABLED      3

/* Fields that contradict each other (one warning each, naming both fields
 * and their values): RU state against RU disabled and Armed RU (TS-0006 4.1,
 * 4.1.3), BU state against the armed RU (4.1.1), an EC-Link error while the
 * BU goes on (TS-0007 9: an EC-Link error locks the BU in Initial). The same
 * rules and texts as lua/eglink.lua and the EC-Link images. */
static void
eglink_check_disagree(eglink_payload_t *p, const eglink_vrpi_fields_t *f)
{
    const char *bu = val_to_str_const(f->bu_state, eglink_bu_state_vals, "Unknown");
    const char *ru = val_to_str_const(f->ru_state, eglink_ru_state_vals, "Unknown");
    const char *dis = val_to_str_const(f->ru_disabled, eglink_ru_disabled_vals, "Unknown");

    if (f->have_ru_state && f->have_ru_disabled) {
        if (f->ru_state == EGLINK_RU_STATE_ENABLED && f->ru_disabled >= 1 && f->ru_disabled <= 3)
            eglink_value_finding(p, f->disabled_ti, &ei_eglink_fields_disagree,
                "RU state %s (%u) but RU disabled %s (%u): an enabled RU is not disabled",
                ru, f->ru_state, dis, f->ru_disabled);
        else if (f->ru_state == EGLINK_RU_STATE_ARMED && f->ru_disabled == 0)
            eglink_value_finding(p, f->disabled_ti, &ei_eglink_fields_disagree,
                "RU state %s (%u) but RU disabled %s (%u): Armed means movements are disabled, "
                "by tilting or inactivity", ru, f->ru_state, dis, f->ru_disabled);
    }
    if (f->have_armed && f->have_ru_state && f->armed_ru != 0 && f->ru_state == EGLINK_RU_STATE_INITIAL)
        eglink_value_finding(p, f->ru_ti, &ei_eglink_fields_disagree,
            "Armed RU 0x%04x but RU state %s (%u): Initial means no RU is armed yet",
            f->armed_ru, ru, f->ru_state);
    if (f->have_armed && f->bu_state == EGLINK_BU_STATE_DISARMED && f->armed_ru != 0)
        eglink_value_finding(p, f->bu_ti, &ei_eglink_fields_disagree,
            "BU state %s (0x%02x) but Armed RU 0x%04x: a disarmed BU is armed against no RU",
            bu, f->bu_state, f->armed_ru);
    else if (f->have_armed && f->armed_ru == 0 &&
             (f->bu_state == EGLINK_BU_STATE_ARMED || f->bu_state == EGLINK_BU_STATE_STOPPED))
        eglink_value_finding(p, f->bu_ti, &ei_eglink_fields_disagree,
            "BU state %s (0x%02x) but Armed RU 0: in that state the BU is armed against an RU",
            bu, f->bu_state);
    if (f->have_ru_state && f->bu_state == EGLINK_BU_STATE_STOPPED &&
        (f->ru_state == EGLINK_RU_STATE_ARMED || f->ru_state == EGLINK_RU_STATE_ENABLED))
        eglink_value_finding(p, f->bu_ti, &ei_eglink_fields_disagree,
            "BU state %s (0x%02x) but RU state %s (%u): the BU stops when its RU signals stop "
            "(RU state Stopped)", bu, f->bu_state, ru, f->ru_state);
    if (f->have_ec_link && try_val_to_str(f->ec_link, eglink_link_fault_vals) &&
        try_val_to_str(f->bu_state, eglink_bu_state_vals) &&
        f->bu_state != EGLINK_BU_STATE_INITIAL && f->bu_state != EGLINK_BU_STATE_LINK_ERROR)
        eglink_value_finding(p, f->ec_ti, &ei_eglink_fields_disagree,
            "EC-Link status %s (%u) but BU state %s (0x%02x): an EC-Link error holds the BU in Initial",
            val_to_str_const(f->ec_link, eglink_link_status_vals, "Unknown"), f->ec_link, bu, f->bu_state);
}

static void
eglink_check_percent(eglink_payload_t *p, proto_item *ti, expert_field *ei, const char *name,
                     guint32 value)
{
    if (value > 100)
        eglink_undefined(p, ti, ei, "%s %u %% is above 100 %%", name, value);
}

/* With Armed RU 0 every RU field after it must be 0: name the ones that are not. */
static void
eglink_check_unarmed(eglink_payload_t *p, proto_item *armed_ti)
{
    static const struct {
        int offset;
        int len;
        const char *name;
    } ru_fields[] = {
        { 8, 1, "RU state" }, { 9, 1, "RU battery" }, { 10, 1, "RU C-Link RSSI" },
        { 11, 1, "RU cable" }, { 12, 1, "RU docked" }, { 13, 1, "RU disabled" },
        { 14, 2, "joystick 1" }, { 16, 2, "joystick 2" }, { 18, 2, "joystick 3" },
        { 20, 2, "joystick 4" }, { 22, 2, "switch 1" }, { 24, 2, "switch 2" },
        { 26, 2, "switch 3" }, { 28, 2, "switch 4" }, { 30, 2, "switch 5" },
        { 32, 2, "switch 6" }, { 34, 2, "switch 7" }, { 36, 2, "switch 8" },
        { 38, 1, "encoder" }, { 39, 1, "encoder switch" },
    };
    wmem_strbuf_t *names = wmem_strbuf_new(p->pinfo->pool, "");
    guint i;

    for (i = 0; i < array_length(ru_fields); i++) {
        if (ru_fields[i].offset + ru_fields[i].len > p->cap)
            break;
        if ((ru_fields[i].len == 1 ? tvb_get_uint8(p->tvb, p->base + ru_fields[i].offset)
                                   : tvb_get_letohs(p->tvb, p->base + ru_fields[i].offset)) != 0)
            wmem_strbuf_append_printf(names, "%s%s", wmem_strbuf_get_len(names) ? ", " : "",
                                      ru_fields[i].name);
    }
    if (wmem_strbuf_get_len(names))
        eglink_undefined(p, armed_ti, &ei_eglink_unarmed_data,
            "No RU is armed (Armed RU 0) but these RU fields are not 0: %s",
            wmem_strbuf_get_str(names));
}

/* Payload bytes both in the packet and in the capture. */
static int
eglink_payload_captured(const eglink_payload_t *p)
{
    return p->cap;
}

/* Whether the ES-Link relays are open: below Disarmed, or with the armed RU
 * stopped. FALSE when the capture cannot tell (RU state cut off by the snap
 * length); a packet without an RU state is judged by its BU state. */
static gboolean
eglink_vrpi_relays(const eglink_payload_t *p, guint32 bu_state, gboolean *open)
{
    *open = bu_state < EGLINK_BU_STATE_DISARMED;
    if (*open || p->len < 9)
        return TRUE;
    if (eglink_payload_captured(p) < 9)
        return FALSE;
    *open = tvb_get_uint8(p->tvb, p->base + 8) == EGLINK_RU_STATE_STOPPED;
    return TRUE;
}

/* Info of a VRPI names what each value is: "BU=Armed RU 0xbeef=Enabled
 * J1=-1000", the unarmed RUs while the BU is Disarmed, then [relays open].
 * Written from the bytes at hand before the tree, so that a frame cut by the
 * snap length still says whether the relays are open. */
static void
eglink_vrpi_info(const eglink_payload_t *p, guint32 bu_state, gboolean relays_open)
{
    int have = eglink_payload_captured(p);
    guint32 armed_ru, ru_state;
    gint16 joystick;
    int i;

    col_append_fstr(p->pinfo->cinfo, COL_INFO, " BU=%s",
                    eglink_value_name(p->pinfo, bu_state, eglink_bu_state_vals));
    if (have >= 3 && bu_state == EGLINK_BU_STATE_DISARMED)
        col_append_fstr(p->pinfo->cinfo, COL_INFO, " Unarmed RUs=%u", tvb_get_uint8(p->tvb, p->base + 2));
    /* the RU part: when an RU is armed, or the RU state says otherwise */
    if (have >= 8) {
        armed_ru = tvb_get_letohs(p->tvb, p->base + 6);
        ru_state = have >= 9 ? tvb_get_uint8(p->tvb, p->base + 8) : 0;
        if (armed_ru != 0 || ru_state != 0) {
            col_append_fstr(p->pinfo->cinfo, COL_INFO, " RU 0x%04x", armed_ru);
            if (have >= 9)
                col_append_fstr(p->pinfo->cinfo, COL_INFO, "=%s",
                                eglink_value_name(p->pinfo, ru_state, eglink_ru_state_vals));
        }
    }
    for (i = 0; i < 4 && have >= 16 + 2 * i; i++) {
        joystick = (gint16)tvb_get_letohs(p->tvb, p->base + 14 + 2 * i);
        if (joystick)
            col_append_fstr(p->pinfo->cinfo, COL_INFO, " J%d=%d", i + 1, joystick);
    }
    if (relays_open)
        col_append_str(p->pinfo->cinfo, COL_INFO, " [relays open]");
}

/* VRPI: BU status and the armed RU's controls. Info: eglink_vrpi_info(), and
 * [undefined] after any undefined or out-of-range value. */
static void
dissect_eglink_vrpi(eglink_payload_t *p, eglink_info_t *info)
{
    proto_item *ti, *bu_ti, *armed_ti, *ru_ti, *link_ti[3] = { NULL, NULL, NULL };
    guint32 bu_state, value, armed_ru = 0, ru_state, link[3] = { 0, 0, 0 };
    gint32 svalue;
    gboolean have_armed, relays_known, relays_open;
    eglink_vrpi_fields_t fields;
    int i;

    if (!eglink_add_uint(p, hf_eglink_bu_state, 0, 1, &bu_state, &bu_ti)) {
        col_append_str(p->pinfo->cinfo, COL_INFO, " (truncated)");
        return;
    }
    info->has_bu_state = TRUE;
    info->bu_state = (guint8)bu_state;
    relays_known = eglink_vrpi_relays(p, bu_state, &relays_open);
    eglink_vrpi_info(p, bu_state, relays_known && relays_open);
    if (try_val_to_str(bu_state, eglink_bu_state_vals) == NULL) {
        eglink_show_unknown(bu_ti, hf_eglink_bu_state, bu_state);
        eglink_undefined(p, bu_ti, &ei_eglink_bu_state_unknown,
            "BU state Unknown (0x%02x): not defined in TS-0006", bu_state);
    }

    /* ES-Link relays, right below the BU state */
    if (relays_known) {
        ti = proto_tree_add_boolean(p->tree, hf_eglink_relays_open, p->tvb, p->base, 1, relays_open);
        proto_item_set_generated(ti);
    }
    if (bu_state < EGLINK_BU_STATE_DISARMED)
        eglink_value_finding(p, bu_ti, &ei_eglink_relays_open,
            "ES-Link relays open: BU state %s (0x%02x), %s",
            val_to_str_const(bu_state, eglink_bu_state_vals, "Unknown"), bu_state,
            val_to_str_const(bu_state, eglink_bu_state_advice, "an undefined state below Disarmed"));

    if (eglink_add_uint(p, hf_eglink_vlaps, 1, 1, &value, &ti) && value > 3)
        eglink_undefined(p, ti, &ei_eglink_vlaps_range, "%u VLAPs reported: a BU has at most 3", value);
    eglink_add_uint(p, hf_eglink_unarmed_rus, 2, 1, &value, NULL);
    memset(&fields, 0, sizeof fields);
    fields.bu_state = bu_state;
    fields.bu_ti = bu_ti;
    if (eglink_add_uint(p, hf_eglink_eg_link_status, 3, 1, &link[0], &link_ti[0])) {
        eglink_check_link_status(p, link_ti[0], hf_eglink_eg_link_status, "EG-Link status", link[0]);
        eglink_check_link_fault(p, link_ti[0], "EG-Link status", link[0]);
    }
    if (eglink_add_uint(p, hf_eglink_ec_link_status, 4, 1, &link[1], &link_ti[1])) {
        eglink_check_link_status(p, link_ti[1], hf_eglink_ec_link_status, "EC-Link status", link[1]);
        eglink_check_link_fault(p, link_ti[1], "EC-Link status", link[1]);
        fields.have_ec_link = TRUE;
        fields.ec_link = link[1];
        fields.ec_ti = link_ti[1];
    }
    if (eglink_add_uint(p, hf_eglink_c_link_status, 5, 1, &link[2], &link_ti[2])) {
        eglink_check_link_status(p, link_ti[2], hf_eglink_c_link_status, "C-Link status", link[2]);
        eglink_check_link_fault(p, link_ti[2], "C-Link status", link[2]);
    }

    have_armed = eglink_add_uint(p, hf_eglink_armed_ru, 6, 2, &armed_ru, &armed_ti);
    fields.have_armed = have_armed;
    fields.armed_ru = armed_ru;
    for (i = 0; i < 3; i++)
        eglink_check_passive(p, link_ti[i], i, link[i], have_armed, armed_ru);
    fields.have_ru_state = eglink_add_uint(p, hf_eglink_ru_state, 8, 1, &ru_state, &ru_ti);
    fields.ru_state = ru_state;
    fields.ru_ti = ru_ti;
    if (fields.have_ru_state) {
        if (ru_state == EGLINK_RU_STATE_STOPPED)
            eglink_value_finding(p, ru_ti, &ei_eglink_ru_state_stopped,
                "RU stopped (stop switch, free-fall/shock sensor or RU fault): ES-Link relays open");
        else if (ru_state == EGLINK_RU_STATE_DISARMED)
            /* TS-0006 4.1.3: Disarmed is used inside the BU only */
            eglink_value_finding(p, ru_ti, &ei_eglink_ru_state_disarmed,
                "RU state 1 (Disarmed) on the wire: TS-0006 uses it only inside the BU");
        else if (try_val_to_str(ru_state, eglink_ru_state_vals) == NULL) {
            eglink_show_unknown(ru_ti, hf_eglink_ru_state, ru_state);
            eglink_undefined(p, ru_ti, &ei_eglink_ru_state_unknown,
                "RU state Unknown (0x%02x): defined are 0..4", ru_state);
        }
    }

    if (eglink_add_uint(p, hf_eglink_ru_battery, 9, 1, &value, &ti))
        eglink_check_percent(p, ti, &ei_eglink_ru_battery_range, "RU battery", value);
    if (eglink_add_uint(p, hf_eglink_ru_rssi, 10, 1, &value, &ti))
        eglink_check_percent(p, ti, &ei_eglink_ru_rssi_range, "RU C-Link RSSI", value);
    if (eglink_add_uint(p, hf_eglink_ru_cable, 11, 1, &value, &ti))
        eglink_check_flag(p, ti, hf_eglink_ru_cable, "RU cable", value);
    if (eglink_add_uint(p, hf_eglink_ru_docked, 12, 1, &value, &ti))
        eglink_check_flag(p, ti, hf_eglink_ru_docked, "RU docked", value);
    fields.have_ru_disabled = eglink_add_uint(p, hf_eglink_ru_disabled, 13, 1, &value, &ti);
    fields.ru_disabled = value;
    fields.disabled_ti = ti;
    if (fields.have_ru_disabled && try_val_to_str(value, eglink_ru_disabled_vals) == NULL) {
        eglink_show_unknown(ti, hf_eglink_ru_disabled, value);
        eglink_undefined(p, ti, &ei_eglink_ru_disabled_unknown,
            "RU disabled reason Unknown (0x%02x): defined are 0 enabled, 1 tilted, 2 inactivity, "
            "3 other", value);
    }

    for (i = 0; i < 4; i++) {
        if (!eglink_add_int(p, hf_eglink_joystick[i], 14 + 2 * i, 2, &svalue, &ti))
            break;
        if (svalue < -EGLINK_JOYSTICK_LIMIT || svalue > EGLINK_JOYSTICK_LIMIT)
            eglink_undefined(p, ti, &ei_eglink_joystick_range,
                "Joystick %d position %d is outside -1000..+1000", i + 1, svalue);
    }
    for (i = 0; i < 8; i++) {
        if (!eglink_add_int(p, hf_eglink_switch[i], 22 + 2 * i, 2, &svalue, &ti))
            break;
    }
    eglink_add_uint(p, hf_eglink_encoder, 38, 1, &value, NULL);
    if (eglink_add_uint(p, hf_eglink_encoder_switch, 39, 1, &value, &ti))
        eglink_check_flag(p, ti, hf_eglink_encoder_switch, "Encoder switch", value);
    eglink_check_payload_spare(p, 40, 6);

    if (have_armed && armed_ru == 0)
        eglink_check_unarmed(p, armed_ti);
    eglink_check_disagree(p, &fields);

    if (p->undefined)
        col_append_str(p->pinfo->cinfo, COL_INFO, " [undefined]");
}

static dissector_table_t eglink_data_table;

/* Hands an application data area to whoever registered for it in the
 * "eglink.data" table (see packet-eglink.h); nothing when nobody did. */
void
eglink_data_dissect(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree, const char *area,
                    guint16 origin, guint16 bu_origin)
{
    dissector_handle_t handle = dissector_get_string_handle(eglink_data_table, area);
    guint32 saved = pinfo->match_uint;

    if (!handle)
        return;
    pinfo->match_uint = ((guint32)bu_origin << 16) | origin;
    TRY {
        call_dissector_only(handle, tvb, pinfo, tree, NULL);
    }
    FINALLY {
        pinfo->match_uint = saved;
    }
    ENDTRY;
}

/* VRPO: one fragment of the controller's periodic data. */
static void
dissect_eglink_vrpo(eglink_payload_t *p, eglink_info_t *info)
{
    guint32 pkt;
    int data_len;

    if (!eglink_add_uint(p, hf_eglink_packet_number, 0, 2, &pkt, NULL)) {
        col_append_str(p->pinfo->cinfo, COL_INFO, " (truncated)");
        return;
    }
    /* Of a cut packet, the data the capture holds; the burst is tracked by
     * the length in the packet. */
    eglink_add_bytes(p, hf_eglink_periodic_data, 2, p->len - 2, NULL);
    data_len = MAX(0, p->len - 2);
    info->has_packet_number = TRUE;
    info->packet_number = (guint16)pkt;
    info->periodic_offset = p->base + 2;
    info->periodic_len = data_len;
    col_append_fstr(p->pinfo->cinfo, COL_INFO, " Pkt=%u %d bytes", pkt, data_len);
}

/* VRCI/VRCO (with_data) and VRAI/VRAO: command ID first. */
static void
dissect_eglink_command(eglink_payload_t *p, eglink_info_t *info, gboolean with_data)
{
    int data_len;

    guint32 cmd;

    if (!eglink_add_uint(p, hf_eglink_command_id, 0, 2, &cmd, NULL)) {
        col_append_str(p->pinfo->cinfo, COL_INFO, " (truncated)");
        return;
    }
    info->has_command_id = TRUE;
    info->command_id = (guint16)cmd;
    col_append_fstr(p->pinfo->cinfo, COL_INFO, " Cmd=%u", cmd);
    if (with_data) {
        eglink_check_payload_spare(p, 2, 4);
        data_len = eglink_add_bytes(p, hf_eglink_command_data, 6, 16, NULL);
        if (data_len == 16)
            eglink_data_dissect(tvb_new_subset_length(p->tvb, p->base + 6, 16), p->pinfo, p->tree,
                                info->type == EGLINK_TYPE_VRCI ? "vrci" : "vrco", info->origin, 0);
    }
}

/* Expected payload size per type: [min, max]. */
static void
eglink_type_sizes(eglink_type_t type, int *min, int *max)
{
    switch (type) {
    case EGLINK_TYPE_VRPI:
        *min = *max = EGLINK_VRPI_LEN;
        break;
    case EGLINK_TYPE_VRPO:
        *min = EGLINK_VRPO_MIN_LEN;
        *max = EGLINK_VRPO_MAX_LEN;
        break;
    case EGLINK_TYPE_VRCI:
    case EGLINK_TYPE_VRCO:
        *min = *max = EGLINK_CMD_LEN;
        break;
    case EGLINK_TYPE_VRAI:
    case EGLINK_TYPE_VRAO:
        *min = *max = EGLINK_ACK_LEN;
        break;
    case EGLINK_TYPE_UNKNOWN:
    default:
        *min = 0;
        *max = G_MAXINT;
        break;
    }
}

/* The CRC check of one packet: with the configured variant and byte order,
 * and when that fails, the first other variant and byte order that fits. */
typedef struct {
    gboolean ok;
    guint32 computed;           /* with the configured variant */
    int match;                  /* the other variant that fits, -1 none */
    gboolean match_be;          /* ... stored big-endian */
} eglink_crc_t;

static void
eglink_crc_check(tvbuff_t *tvb, packet_info *pinfo, int crc_offset, eglink_crc_t *c)
{
    guint32 stored_le = tvb_get_letohl(tvb, crc_offset);
    guint32 stored_be = tvb_get_ntohl(tvb, crc_offset);
    guint32 computed;
    int v;

    c->computed = eglink_crc_compute(tvb, pinfo, crc_offset, (eglink_crc_variant_t)eglink_crc_variant);
    c->ok = (eglink_crc_order == EGLINK_CRC_BE ? stored_be : stored_le) == c->computed;
    c->match = -1;
    c->match_be = FALSE;
    for (v = 0; !c->ok && v < EGLINK_CRC_NUM_VARIANTS; v++) {
        computed = v == eglink_crc_variant ? c->computed
                                           : eglink_crc_compute(tvb, pinfo, crc_offset, (eglink_crc_variant_t)v);
        if (computed == stored_le && (v != eglink_crc_variant || eglink_crc_order != EGLINK_CRC_LE)) {
            c->match = v;
            break;
        }
        if (computed == stored_be && (v != eglink_crc_variant || eglink_crc_order != EGLINK_CRC_BE)) {
            c->match = v;
            c->match_be = TRUE;
            break;
        }
    }
}

/* A CRC that fails in every variant and byte order: the packet is
 * corrupted, and no value in it is trusted. */
static gboolean
eglink_crc_corrupted(const eglink_crc_t *c)
{
    return !c->ok && c->match < 0;
}

/* CRC: the check's result; on failure which variant fits, or that the
 * packet's values are not trusted (said once, instead of a finding per
 * value its corrupted bytes make undefined). */
static gboolean
dissect_eglink_crc(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree, int crc_offset, const eglink_crc_t *c)
{
    proto_item *ti;

    ti = proto_tree_add_checksum(tree, tvb, crc_offset, hf_eglink_crc, hf_eglink_crc_status,
                                 NULL, pinfo, c->computed,
                                 eglink_crc_order == EGLINK_CRC_BE ? ENC_BIG_ENDIAN : ENC_LITTLE_ENDIAN,
                                 PROTO_CHECKSUM_VERIFY);
    if (c->ok)
        return TRUE;

    col_append_str(pinfo->cinfo, COL_INFO, " [bad CRC]");
    if (c->match < 0) {
        expert_add_info_format(pinfo, ti, &ei_eglink_crc_bad,
            "Bad CRC [should be 0x%08x]: no CRC variant fits, the packet is corrupted: its payload "
            "values are not trusted, none is judged", c->computed);
        return FALSE;
    }
    expert_add_info_format(pinfo, ti, &ei_eglink_crc_bad, "Bad CRC [should be 0x%08x]", c->computed);
    expert_add_info_format(pinfo, ti, &ei_eglink_crc_variant,
        "CRC matches %s, %s-endian: set the preference (eglink.crc_variant: %s, eglink.crc_byte_order: %s)",
        eglink_crc_variant_names[c->match], c->match_be ? "big" : "little",
        eglink_crc_variant_vals[c->match].name, c->match_be ? "be" : "le");
    return FALSE;
}

/* Adds a header field if the packet, and the capture, are long enough for it
 * (have: the smaller of the two lengths). */
static gboolean
eglink_add_header_uint(proto_tree *tree, tvbuff_t *tvb, int hf, int off, int len, int have,
                       guint32 *value, proto_item **item)
{
    *value = 0;
    *item = NULL;
    if (off + len > have)
        return FALSE;
    *item = proto_tree_add_item_ret_uint(tree, hf, tvb, off, len, ENC_LITTLE_ENDIAN, value);
    return TRUE;
}

/* A packet cut by the capture ends as every such packet does in Wireshark,
 * "[Packet size limited during capture]", once it is decoded and analysed
 * from the bytes the capture holds. */
static void
eglink_end_of_capture(tvbuff_t *tvb, int captured, int reported)
{
    if (captured < reported)
        tvb_ensure_bytes_exist(tvb, 0, reported);
}

static int
dissect_eglink(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree, void *data _U_)
{
    proto_item *eglink_item, *ti, *size_ti = NULL;
    proto_tree *eglink_tree;
    eglink_info_t info;
    eglink_payload_t p;
    eglink_crc_t crc;
    guint32 value;
    int reported = (int)tvb_reported_length(tvb);
    int captured = (int)tvb_captured_length(tvb);
    int have = MIN(reported, captured);     /* bytes in the packet and in the capture */
    int min_len, max_len;
    const char *id;

    if (tvb_captured_length(tvb) < 2 || tvb_get_uint8(tvb, 0) != 'V' || tvb_get_uint8(tvb, 1) != 'R')
        return 0;

    memset(&info, 0, sizeof info);
    info.type = EGLINK_TYPE_UNKNOWN;

    col_set_str(pinfo->cinfo, COL_PROTOCOL, "EG-Link");
    col_clear(pinfo->cinfo, COL_INFO);

    eglink_item = proto_tree_add_item(tree, proto_eglink, tvb, 0, -1, ENC_NA);
    eglink_tree = proto_item_add_subtree(eglink_item, ett_eglink);

    id = tvb_format_text(pinfo->pool, tvb, 0, MIN(have, 4));
    col_add_str(pinfo->cinfo, COL_INFO, id);
    proto_item_append_text(eglink_item, ", %s", id);
    if (have >= 4) {
        info.type = eglink_type_from_id(tvb_get_uint8(tvb, 2), tvb_get_uint8(tvb, 3));
        ti = proto_tree_add_item(eglink_tree, hf_eglink_type, tvb, 0, 4, ENC_ASCII);
        proto_item_append_text(ti, " (%s)", val_to_str_const(info.type, eglink_type_descr, ""));
    }
    if (info.type == EGLINK_TYPE_UNKNOWN && (have >= 4 || reported < 4)) {
        col_append_str(pinfo->cinfo, COL_INFO, " (unknown type)");
        expert_add_info_format(pinfo, eglink_item, &ei_eglink_type_unknown,
            "Unknown packet type %s: TS-0006 defines VRPI, VRPO, VRCI, VRCO, VRAI and VRAO; "
            "only the header and CRC are decoded", id);
    }

    /* Header */
    if (eglink_add_header_uint(eglink_tree, tvb, hf_eglink_revision, 4, 2, have, &value, &ti)) {
        info.revision = (guint16)value;
        if (value != 0)
            expert_add_info_format(pinfo, ti, &ei_eglink_revision_unknown,
                "Revision %u: only revision 0 (the TS-0006 layout) is known, the payload may differ",
                value);
    }
    if (eglink_add_header_uint(eglink_tree, tvb, hf_eglink_origin, 6, 2, have, &value, &ti)) {
        info.origin = (guint16)value;
        if (info.type != EGLINK_TYPE_UNKNOWN && !eglink_is_input(info.type) && value != 0)
            expert_add_info_format(pinfo, ti, &ei_eglink_origin_nonzero,
                "Origin is 0x%04x in a %s from the machine controller: it must be 0", value, id);
        else if (eglink_is_input(info.type) && value == 0)
            expert_add_info_format(pinfo, ti, &ei_eglink_origin_zero,
                "Origin is 0 in a %s from the BU: the BU should send its unique ID", id);
    }
    if (eglink_add_header_uint(eglink_tree, tvb, hf_eglink_serial, 8, 2, have, &value, &ti)) {
        info.serial = (guint16)value;
        info.has_serial = TRUE;
        proto_item_append_text(eglink_item, ", Serial %u", value);
    }
    if (eglink_add_header_uint(eglink_tree, tvb, hf_eglink_size, 10, 2, have, &value, &size_ti))
        info.size = (guint16)value;
    if (eglink_add_header_uint(eglink_tree, tvb, hf_eglink_spare, 12, 4, have, &value, &ti) && value != 0)
        expert_add_info_format(pinfo, ti, &ei_eglink_spare_nonzero,
            "Header spare is 0x%08x, not 0: reserved for future use, the sender may use a "
            "newer layout than TS-0006", value);

    /* Cut by the capture (snap length): said once, then decoded and analysed
     * from what it holds, never from bytes it does not hold. */
    info.cut = captured < reported;
    if (info.cut) {
        expert_add_info_format(pinfo, eglink_item, &ei_eglink_cut,
            "Packet cut by the capture (snaplen): %d of %d bytes captured; decoded as far as "
            "captured, CRC not checked, counted as received", captured, reported);
        if (reported < EGLINK_MIN_LEN || info.type == EGLINK_TYPE_UNKNOWN || !info.has_serial)
            info.cut = FALSE;   /* too little of it to analyse: as before */
    }
    if (have < 4 && reported >= 4) {
        /* not even the packet ID in the capture: nothing to decode */
        eglink_end_of_capture(tvb, captured, reported);
        return reported;
    }

    if (reported < EGLINK_MIN_LEN) {
        expert_add_info_format(pinfo, eglink_item, &ei_eglink_too_short,
            "Packet is %d bytes, too short for packet ID, header and CRC (20 bytes)", reported);
        col_append_str(pinfo->cinfo, COL_INFO, " (too short)");
        eglink_analysis_dissect(tvb, pinfo, eglink_tree, eglink_item, &info);
        eglink_end_of_capture(tvb, captured, reported);
        return reported;
    }

    /* Payload: everything between the header and the CRC at the end of the datagram. */
    p.tvb = tvb;
    p.pinfo = pinfo;
    p.base = EGLINK_HEADER_LEN;
    p.len = reported - EGLINK_MIN_LEN;
    p.cap = MAX(0, MIN(p.len, captured - EGLINK_HEADER_LEN));
    p.undefined = FALSE;
    /* (checked before the payload: a corrupted packet's values are not judged) */
    memset(&crc, 0, sizeof crc);
    crc.match = -1;
    if (captured >= reported)
        eglink_crc_check(tvb, pinfo, reported - EGLINK_CRC_LEN, &crc);
    p.untrusted = captured >= reported && eglink_crc_corrupted(&crc);
    info.size_ok = TRUE;
    if (info.size != p.len) {
        info.size_ok = FALSE;
        expert_add_info_format(pinfo, size_ti, &ei_eglink_size_mismatch,
            "Size says %u payload bytes but the UDP payload carries %d (UDP payload length - 20)",
            info.size, p.len);
    }
    eglink_type_sizes(info.type, &min_len, &max_len);
    if (p.len < min_len || p.len > max_len) {
        info.size_ok = FALSE;
        if (min_len == max_len)
            expert_add_info_format(pinfo, size_ti, &ei_eglink_size_invalid,
                "A %s payload is %d bytes, this one has %d: decoded as far as it goes",
                id, min_len, p.len);
        else
            expert_add_info_format(pinfo, size_ti, &ei_eglink_size_invalid,
                "A %s payload is %d to %d bytes (packet number + up to 488 bytes of data), "
                "this one has %d: decoded as far as it goes", id, min_len, max_len, p.len);
    }

    /* (of a cut packet, the item covers what the capture holds) */
    if (captured >= p.base) {
        ti = proto_tree_add_item(eglink_tree, hf_eglink_payload, tvb, p.base, MIN(p.len, p.cap), ENC_NA);
        proto_item_append_text(ti, " (%d byte%s)", p.len, p.len == 1 ? "" : "s");
        p.tree = proto_item_add_subtree(ti, ett_eglink_payload);
    } else {
        p.tree = eglink_tree;
    }
    switch (info.type) {
    case EGLINK_TYPE_VRPI:
        dissect_eglink_vrpi(&p, &info);
        break;
    case EGLINK_TYPE_VRPO:
        dissect_eglink_vrpo(&p, &info);
        break;
    case EGLINK_TYPE_VRCI:
    case EGLINK_TYPE_VRCO:
        dissect_eglink_command(&p, &info, TRUE);
        break;
    case EGLINK_TYPE_VRAI:
    case EGLINK_TYPE_VRAO:
        dissect_eglink_command(&p, &info, FALSE);
        break;
    case EGLINK_TYPE_UNKNOWN:
    default:
        eglink_add_bytes(&p, hf_eglink_unknown_payload, 0, p.len, NULL);
        col_append_fstr(pinfo->cinfo, COL_INFO, " %d bytes", p.len);
        break;
    }
    if (info.type != EGLINK_TYPE_UNKNOWN && p.len > max_len)
        eglink_add_bytes(&p, hf_eglink_extra_payload, max_len, p.len - max_len, NULL);

    if (captured >= reported)
        info.crc_ok = dissect_eglink_crc(tvb, pinfo, eglink_tree, reported - EGLINK_CRC_LEN, &crc);
    else
        info.crc_ok = info.cut;     /* not checked: counted as received when analysable */

    eglink_analysis_dissect(tvb, pinfo, eglink_tree, eglink_item, &info);
    eglink_end_of_capture(tvb, captured, reported);
    return reported;
}

/* Heuristic: "VR", a defined type, and a Size that matches the datagram. */
static eglink_heur_bool_t
dissect_eglink_heur(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree, void *data)
{
    int min_len, max_len;
    eglink_type_t type;
    int payload_len;

    if (!eglink_heuristic)
        return FALSE;
    if (tvb_captured_length(tvb) < EGLINK_HEADER_LEN || tvb_reported_length(tvb) < EGLINK_MIN_LEN)
        return FALSE;
    if (tvb_get_uint8(tvb, 0) != 'V' || tvb_get_uint8(tvb, 1) != 'R')
        return FALSE;
    type = eglink_type_from_id(tvb_get_uint8(tvb, 2), tvb_get_uint8(tvb, 3));
    if (type == EGLINK_TYPE_UNKNOWN)
        return FALSE;
    payload_len = (int)tvb_reported_length(tvb) - EGLINK_MIN_LEN;
    if (tvb_get_letohs(tvb, 10) != payload_len)
        return FALSE;
    eglink_type_sizes(type, &min_len, &max_len);
    if (payload_len < min_len || payload_len > max_len)
        return FALSE;
    dissect_eglink(tvb, pinfo, tree, data);
    return TRUE;
}

void
proto_register_eglink(void)
{
    static hf_register_info hf[] = {
        { &hf_eglink_type,
          { "Packet ID", "eglink.type", FT_STRING, BASE_NONE, NULL, 0x0,
            "Packet type: VRPI, VRPO, VRCI, VRCO, VRAI or VRAO", HFILL } },
        { &hf_eglink_revision,
          { "Revision", "eglink.revision", FT_UINT16, BASE_DEC, NULL, 0x0,
            "Payload layout revision, 0 for TS-0006", HFILL } },
        { &hf_eglink_origin,
          { "Origin", "eglink.origin", FT_UINT16, BASE_HEX, NULL, 0x0,
            "Unique ID of the sending BU, 0 from the machine controller", HFILL } },
        { &hf_eglink_serial,
          { "Serial", "eglink.serial", FT_UINT16, BASE_DEC, NULL, 0x0,
            "Packet serial number, counted by the sender", HFILL } },
        { &hf_eglink_size,
          { "Size", "eglink.size", FT_UINT16, BASE_DEC, NULL, 0x0,
            "Payload size in bytes", HFILL } },
        { &hf_eglink_spare,
          { "Spare", "eglink.spare", FT_UINT32, BASE_HEX, NULL, 0x0,
            "Header spare, 0", HFILL } },
        { &hf_eglink_payload,
          { "Payload", "eglink.payload", FT_NONE, BASE_NONE, NULL, 0x0,
            NULL, HFILL } },
        { &hf_eglink_payload_spare,
          { "Payload spare", "eglink.payload_spare", FT_BYTES, BASE_NONE, NULL, 0x0,
            "Payload spare bytes, 0", HFILL } },
        { &hf_eglink_extra_payload,
          { "Extra payload", "eglink.extra_payload", FT_BYTES, BASE_NONE, NULL, 0x0,
            "Bytes beyond the payload size of this packet type", HFILL } },
        { &hf_eglink_unknown_payload,
          { "Payload data", "eglink.unknown_payload", FT_BYTES, BASE_NONE, NULL, 0x0,
            "Payload of an unknown packet type", HFILL } },
        { &hf_eglink_crc,
          { "CRC", "eglink.crc", FT_UINT32, BASE_HEX, NULL, 0x0,
            "CRC-32 over packet ID, header and payload", HFILL } },
        { &hf_eglink_crc_status,
          { "CRC status", "eglink.crc.status", FT_UINT8, BASE_NONE, VALS(proto_checksum_vals), 0x0,
            NULL, HFILL } },

        { &hf_eglink_bu_state,
          { "BU state", "eglink.bu_state", FT_UINT8, BASE_HEX, VALS(eglink_bu_state_vals), 0x0,
            "State of the BU; below 0x10 the ES-Link relays are open", HFILL } },
        { &hf_eglink_relays_open,
          { "ES-Link relays", "eglink.relays_open", FT_BOOLEAN, BASE_NONE, TFS(&tfs_eglink_relays), 0x0,
            "Open when the BU state is below Disarmed (0x10) or the armed RU is stopped", HFILL } },
        { &hf_eglink_vlaps,
          { "VLAPs", "eglink.vlaps", FT_UINT8, BASE_DEC, NULL, 0x0,
            "Number of VLAPs connected to the BU (0..3)", HFILL } },
        { &hf_eglink_unarmed_rus,
          { "Unarmed RUs", "eglink.unarmed_rus", FT_UINT8, BASE_DEC, NULL, 0x0,
            "Number of unarmed RUs talking to this BU", HFILL } },
        { &hf_eglink_eg_link_status,
          { "EG-Link status", "eglink.eg_link_status", FT_UINT8, BASE_DEC, VALS(eglink_link_status_vals), 0x0,
            NULL, HFILL } },
        { &hf_eglink_ec_link_status,
          { "EC-Link status", "eglink.ec_link_status", FT_UINT8, BASE_DEC, VALS(eglink_link_status_vals), 0x0,
            NULL, HFILL } },
        { &hf_eglink_c_link_status,
          { "C-Link status", "eglink.c_link_status", FT_UINT8, BASE_DEC, VALS(eglink_link_status_vals), 0x0,
            NULL, HFILL } },
        { &hf_eglink_armed_ru,
          { "Armed RU", "eglink.armed_ru", FT_UINT16, BASE_HEX, NULL, 0x0,
            "Unique ID of the armed RU, 0 when none is armed", HFILL } },
        { &hf_eglink_ru_state,
          { "RU state", "eglink.ru_state", FT_UINT8, BASE_DEC, VALS(eglink_ru_state_vals), 0x0,
            "State of the armed RU", HFILL } },
        { &hf_eglink_ru_battery,
          { "RU battery", "eglink.ru_battery", FT_UINT8, BASE_DEC | BASE_UNIT_STRING, &eglink_units_percent, 0x0,
            "Battery level of the armed RU (0..100 %)", HFILL } },
        { &hf_eglink_ru_rssi,
          { "RU C-Link RSSI", "eglink.ru_rssi", FT_UINT8, BASE_DEC | BASE_UNIT_STRING, &eglink_units_percent, 0x0,
            "C-Link signal level of the armed RU (0..100 %)", HFILL } },
        { &hf_eglink_ru_cable,
          { "RU cable", "eglink.ru_cable", FT_UINT8, BASE_DEC, VALS(eglink_ru_cable_vals), 0x0,
            "1 when the RU runs on cable, 0 on wireless VisionLink", HFILL } },
        { &hf_eglink_ru_docked,
          { "RU docked", "eglink.ru_docked", FT_UINT8, BASE_DEC, VALS(eglink_ru_docked_vals), 0x0,
            "1 when the RU sits in its docking station", HFILL } },
        { &hf_eglink_ru_disabled,
          { "RU disabled", "eglink.ru_disabled", FT_UINT8, BASE_DEC, VALS(eglink_ru_disabled_vals), 0x0,
            "Why the armed RU's movements are disabled (0 = enabled)", HFILL } },
        { &hf_eglink_joystick[0],
          { "Joystick 1", "eglink.joystick1", FT_INT16, BASE_DEC, NULL, 0x0,
            "Position of joystick 1 (-1000..+1000, 0 = passive)", HFILL } },
        { &hf_eglink_joystick[1],
          { "Joystick 2", "eglink.joystick2", FT_INT16, BASE_DEC, NULL, 0x0,
            "Position of joystick 2 (-1000..+1000, 0 = passive)", HFILL } },
        { &hf_eglink_joystick[2],
          { "Joystick 3", "eglink.joystick3", FT_INT16, BASE_DEC, NULL, 0x0,
            "Position of joystick 3 (-1000..+1000, 0 = passive)", HFILL } },
        { &hf_eglink_joystick[3],
          { "Joystick 4", "eglink.joystick4", FT_INT16, BASE_DEC, NULL, 0x0,
            "Position of joystick 4 (-1000..+1000, 0 = passive)", HFILL } },
        { &hf_eglink_switch[0],
          { "Switch 1", "eglink.switch1", FT_INT16, BASE_DEC, NULL, 0x0,
            "State of switch 1 (leftmost)", HFILL } },
        { &hf_eglink_switch[1],
          { "Switch 2", "eglink.switch2", FT_INT16, BASE_DEC, NULL, 0x0,
            "State of switch 2", HFILL } },
        { &hf_eglink_switch[2],
          { "Switch 3", "eglink.switch3", FT_INT16, BASE_DEC, NULL, 0x0,
            "State of switch 3", HFILL } },
        { &hf_eglink_switch[3],
          { "Switch 4", "eglink.switch4", FT_INT16, BASE_DEC, NULL, 0x0,
            "State of switch 4", HFILL } },
        { &hf_eglink_switch[4],
          { "Switch 5", "eglink.switch5", FT_INT16, BASE_DEC, NULL, 0x0,
            "State of switch 5", HFILL } },
        { &hf_eglink_switch[5],
          { "Switch 6", "eglink.switch6", FT_INT16, BASE_DEC, NULL, 0x0,
            "State of switch 6", HFILL } },
        { &hf_eglink_switch[6],
          { "Switch 7", "eglink.switch7", FT_INT16, BASE_DEC, NULL, 0x0,
            "State of switch 7", HFILL } },
        { &hf_eglink_switch[7],
          { "Switch 8", "eglink.switch8", FT_INT16, BASE_DEC, NULL, 0x0,
            "State of switch 8", HFILL } },
        { &hf_eglink_encoder,
          { "Encoder", "eglink.encoder", FT_UINT8, BASE_DEC, NULL, 0x0,
            "Encoder value; wraps around as the encoder turns", HFILL } },
        { &hf_eglink_encoder_switch,
          { "Encoder switch", "eglink.encoder_switch", FT_UINT8, BASE_DEC, VALS(eglink_encoder_switch_vals), 0x0,
            "1 while the encoder is pushed down", HFILL } },

        { &hf_eglink_packet_number,
          { "Packet number", "eglink.packet_number", FT_UINT16, BASE_DEC, NULL, 0x0,
            "Number of this packet within a split periodic output, from 0", HFILL } },
        { &hf_eglink_periodic_data,
          { "Periodic data", "eglink.periodic_data", FT_BYTES, BASE_NONE, NULL, 0x0,
            "Periodic process data from the machine controller to the RU application", HFILL } },

        { &hf_eglink_command_id,
          { "Command ID", "eglink.command_id", FT_UINT16, BASE_DEC, NULL, 0x0,
            "Sequential command number; an acknowledge carries the ID it acknowledges", HFILL } },
        { &hf_eglink_command_data,
          { "Command data", "eglink.command_data", FT_BYTES, BASE_NONE, NULL, 0x0,
            "Command data between the RU application and the machine controller", HFILL } },
    };

    static gint *ett[] = {
        &ett_eglink,
        &ett_eglink_payload,
    };

    static ei_register_info ei[] = {
        { &ei_eglink_too_short,
          { "eglink.too_short", PI_MALFORMED, PI_ERROR,
            "Packet too short for packet ID, header and CRC", EXPFILL } },
        { &ei_eglink_size_mismatch,
          { "eglink.size.mismatch", PI_MALFORMED, PI_ERROR,
            "Header Size does not match the UDP payload length - 20", EXPFILL } },
        { &ei_eglink_size_invalid,
          { "eglink.size.invalid", PI_MALFORMED, PI_ERROR,
            "Payload size is wrong for this packet type", EXPFILL } },
        { &ei_eglink_type_unknown,
          { "eglink.type.unknown", PI_UNDECODED, PI_WARN,
            "Unknown packet type", EXPFILL } },
        { &ei_eglink_revision_unknown,
          { "eglink.revision.unknown", PI_PROTOCOL, PI_WARN,
            "Unknown revision: only revision 0 is known", EXPFILL } },
        { &ei_eglink_origin_nonzero,
          { "eglink.origin.nonzero", PI_PROTOCOL, PI_WARN,
            "Origin must be 0 in packets from the machine controller", EXPFILL } },
        { &ei_eglink_origin_zero,
          { "eglink.origin.zero", PI_PROTOCOL, PI_WARN,
            "Origin is 0 in a packet from the BU", EXPFILL } },
        { &ei_eglink_spare_nonzero,
          { "eglink.spare.nonzero", PI_PROTOCOL, PI_WARN,
            "Header spare is not 0", EXPFILL } },
        { &ei_eglink_payload_spare_nonzero,
          { "eglink.payload_spare.nonzero", PI_PROTOCOL, PI_WARN,
            "Payload spare bytes are not 0", EXPFILL } },
        { &ei_eglink_crc_bad,
          { "eglink.crc.bad", PI_CHECKSUM, PI_ERROR,
            "Bad CRC", EXPFILL } },
        { &ei_eglink_crc_variant,
          { "eglink.crc.variant", PI_CHECKSUM, PI_WARN,
            "CRC matches another CRC variant or byte order: set the preference", EXPFILL } },
        { &ei_eglink_relays_open,
          { "eglink.bu_state.relays_open", PI_RESPONSE_CODE, PI_WARN,
            "ES-Link relays open", EXPFILL } },
        { &ei_eglink_bu_state_unknown,
          { "eglink.bu_state.unknown", PI_PROTOCOL, PI_ERROR,
            "BU state is not defined", EXPFILL } },
        { &ei_eglink_link_status_unknown,
          { "eglink.link_status.unknown", PI_PROTOCOL, PI_ERROR,
            "Link status is not defined (0..6)", EXPFILL } },
        { &ei_eglink_vlaps_range,
          { "eglink.vlaps.range", PI_PROTOCOL, PI_ERROR,
            "More than 3 VLAPs", EXPFILL } },
        { &ei_eglink_ru_state_stopped,
          { "eglink.ru_state.stopped", PI_RESPONSE_CODE, PI_WARN,
            "RU stopped: ES-Link relays open", EXPFILL } },
        { &ei_eglink_link_status_passive,
          { "eglink.link_status.passive", PI_PROTOCOL, PI_WARN,
            "Link status Passive where TS-0006 does not allow it", EXPFILL } },
        { &ei_eglink_ru_state_disarmed,
          { "eglink.ru_state.disarmed", PI_PROTOCOL, PI_NOTE,
            "RU state Disarmed (used inside the BU only)", EXPFILL } },
        { &ei_eglink_ru_state_unknown,
          { "eglink.ru_state.unknown", PI_PROTOCOL, PI_ERROR,
            "RU state is not defined (0..4)", EXPFILL } },
        { &ei_eglink_ru_battery_range,
          { "eglink.ru_battery.range", PI_PROTOCOL, PI_ERROR,
            "RU battery above 100 %", EXPFILL } },
        { &ei_eglink_ru_rssi_range,
          { "eglink.ru_rssi.range", PI_PROTOCOL, PI_ERROR,
            "RU C-Link RSSI above 100 %", EXPFILL } },
        { &ei_eglink_flag_invalid,
          { "eglink.flag.invalid", PI_PROTOCOL, PI_ERROR,
            "Flag is neither 0 nor 1", EXPFILL } },
        { &ei_eglink_ru_disabled_unknown,
          { "eglink.ru_disabled.unknown", PI_PROTOCOL, PI_ERROR,
            "RU disabled reason is not defined (0..3)", EXPFILL } },
        { &ei_eglink_joystick_range,
          { "eglink.joystick.range", PI_PROTOCOL, PI_ERROR,
            "Joystick position outside -1000..+1000", EXPFILL } },
        { &ei_eglink_unarmed_data,
          { "eglink.armed_ru.unarmed_data", PI_PROTOCOL, PI_ERROR,
            "No RU is armed but RU fields are not 0", EXPFILL } },
        { &ei_eglink_fields_disagree,
          { "eglink.fields_disagree", PI_PROTOCOL, PI_WARN,
            "VRPI fields contradict each other", EXPFILL } },
        { &ei_eglink_link_status_fault,
          { "eglink.link_status.fault", PI_RESPONSE_CODE, PI_WARN,
            "Link status reports a fault (2..5)", EXPFILL } },
        { &ei_eglink_cut,
          { "eglink.cut", PI_UNDECODED, PI_NOTE,
            "Packet cut by the capture (snaplen)", EXPFILL } },
    };

    module_t *eglink_module;
    expert_module_t *expert_eglink;

    proto_eglink = proto_register_protocol("VisionRemote EG-Link", "EG-Link", "eglink");
    proto_register_field_array(proto_eglink, hf, array_length(hf));
    proto_register_subtree_array(ett, array_length(ett));
    expert_eglink = expert_register_protocol(proto_eglink);
    expert_register_field_array(expert_eglink, ei, array_length(ei));

    eglink_handle = register_dissector("eglink", dissect_eglink, proto_eglink);

    eglink_data_table = register_dissector_table(EGLINK_DATA_TABLE, "EG-Link application data",
                                                 proto_eglink, FT_STRING, 0 /* case-sensitive */);
    eglink_module = prefs_register_protocol(proto_eglink, proto_reg_handoff_eglink);
    range_convert_str(wmem_epan_scope(), &eglink_input_ports, EGLINK_DEFAULT_INPUT_PORTS, 65535);
    prefs_register_range_preference(eglink_module, "input_port", "Input UDP port(s)",
        "UDP port(s) the BU sends VRPI, VRCI and VRAI to. The machine controller sends "
        "VRPO, VRCO and VRAO to the port 2 higher, which is registered as well.",
        &eglink_input_ports, 65535);
    prefs_register_enum_preference(eglink_module, "crc_variant", "CRC variant",
        "CRC algorithm of the trailing CRC. TS-0006 specifies CRC-32/MPEG-2; some firmware "
        "computes another variant (the expert info names the one that matches).",
        &eglink_crc_variant, eglink_crc_variant_vals, FALSE);
    prefs_register_enum_preference(eglink_module, "crc_byte_order", "CRC byte order",
        "Byte order of the stored CRC. TS-0006 specifies little-endian.",
        &eglink_crc_order, eglink_crc_order_vals, FALSE);
    prefs_register_bool_preference(eglink_module, "heuristic", "Detect EG-Link on any UDP port",
        "Look for EG-Link packets (\"VR\", a known packet type and a matching Size) on UDP "
        "ports other than the configured ones.",
        &eglink_heuristic);

    eglink_analysis_register(proto_eglink, eglink_module);
}

gboolean
eglink_is_input_port(guint32 port)
{
    return eglink_input_ports && value_is_in_range(eglink_input_ports, port);
}

/* Registers the input ports and the output ports (input + 2) on udp.port. */
static void
eglink_register_ports(void)
{
    wmem_strbuf_t *ports = wmem_strbuf_new(NULL, "");
    guint i;

    if (eglink_registered_ports) {
        dissector_delete_uint_range("udp.port", eglink_registered_ports, eglink_handle);
        wmem_free(wmem_epan_scope(), eglink_registered_ports);
        eglink_registered_ports = NULL;
    }
    for (i = 0; eglink_input_ports && i < eglink_input_ports->nranges; i++) {
        guint32 low = eglink_input_ports->ranges[i].low;
        guint32 high = eglink_input_ports->ranges[i].high;

        wmem_strbuf_append_printf(ports, "%s%u-%u", i ? "," : "", low, high);
        if (low + EGLINK_OUTPUT_PORT_OFFSET <= 65535)
            wmem_strbuf_append_printf(ports, ",%u-%u", low + EGLINK_OUTPUT_PORT_OFFSET,
                                      MIN(high + EGLINK_OUTPUT_PORT_OFFSET, 65535));
    }
    range_convert_str(wmem_epan_scope(), &eglink_registered_ports, wmem_strbuf_get_str(ports), 65535);
    wmem_strbuf_destroy(ports);
    dissector_add_uint_range("udp.port", eglink_registered_ports, eglink_handle);
}

void
proto_reg_handoff_eglink(void)
{
    static gboolean initialized = FALSE;

    if (!initialized) {
        dissector_add_for_decode_as("udp.port", eglink_handle);
        heur_dissector_add("udp", dissect_eglink_heur, "EG-Link over UDP", "eglink_udp",
                           proto_eglink, HEURISTIC_ENABLE);
        initialized = TRUE;
    }
    eglink_register_ports();
}
