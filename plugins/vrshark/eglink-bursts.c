/* eglink-bursts.c
 * VRPO bursts (twin: lua/vrshark/eglink_bursts.luam): a periodic output
 * split over several VRPO packets, the controller's packet numbering learned
 * from its second burst, the rules of TS-0006 4.2 and 5.1.2 on the way, and
 * the reassembly of a complete burst's periodic data, handed to the
 * "eglink.data" table. Registers the reassembly's fields.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "eglink-shared.h"

#include "eglink-compat.h"

#include <epan/reassemble.h>

static int hf_eglink_periodic_data_id = -1;     /* looked up by name: eglink.periodic_data */

static int hf_fragments = -1;
static int hf_fragment = -1;
static int hf_fragment_overlap = -1;
static int hf_fragment_overlap_conflicts = -1;
static int hf_fragment_multiple_tails = -1;
static int hf_fragment_too_long_fragment = -1;
static int hf_fragment_error = -1;
static int hf_fragment_count = -1;
static int hf_reassembled_in = -1;
static int hf_reassembled_length = -1;

static gint ett_fragment = -1;
static gint ett_fragments = -1;

static reassembly_table eglink_reassembly_table;

static const fragment_items eglink_frag_items = {
    &ett_fragment,
    &ett_fragments,
    &hf_fragments,
    &hf_fragment,
    &hf_fragment_overlap,
    &hf_fragment_overlap_conflicts,
    &hf_fragment_multiple_tails,
    &hf_fragment_too_long_fragment,
    &hf_fragment_error,
    &hf_fragment_count,
    &hf_reassembled_in,
    &hf_reassembled_length,
    NULL,
    "VRPO fragments"
};

guint32 eglink_burst_count;

void
eglink_bursts_init(void)
{
    eglink_burst_count = 0;
}

static gboolean
burst_ends_here(const eglink_burst_t *b, int data_len)
{
    if (data_len < EGLINK_VRPO_FRAGMENT_MAX)
        return TRUE;
    return eglink_pref_periodic_size != 0 && b->bytes >= eglink_pref_periodic_size;
}

static void
burst_check_size(const eglink_burst_t *b, eglink_frame_t *fd)
{
    if (eglink_pref_periodic_size != 0 && b->bytes != eglink_pref_periodic_size)
        add_finding(fd, FND_BURST_SIZE, 0, b->bytes, eglink_pref_periodic_size);
}

/* The previous burst ends before this packet starts a new one: complete
 * (all its packets full, its end not shown otherwise) or incomplete. */
static void
burst_close_open(eglink_burst_t *b, eglink_frame_t *fd)
{
    if (!b->open)
        return;
    if (b->quiet) {
        /* the tail of a burst that ended already: said by FND_VRPO_NOT_FULL */
    } else if (!b->broken && eglink_pref_periodic_size == 0) {
        add_finding(fd, FND_BURST_DONE, b->first_frame, b->id, 0);
    } else {
        add_finding(fd, FND_BURST_INCOMPLETE, b->first_frame,
                    b->broken ? b->missing | (b->missing_cut ? EGLINK_BURST_CUT : 0) : b->next, 0);
    }
    b->open = FALSE;
}

/* The packet number a new burst starts with, by the numbering learned;
 * -1 while it is not known (any number starts one). */
static gint32
burst_expected_start(const eglink_burst_t *b)
{
    switch ((eglink_vrpo_numbering_t)b->numbering) {
    case VRPO_NUM_FROM0:
        return 0;
    case VRPO_NUM_FROM1:
        return 1;
    case VRPO_NUM_RUNNING:
        return (guint16)(b->prev_number + 1);
    case VRPO_NUM_UNKNOWN:
    default:
        return -1;
    }
}

/* Learns the numbering at the start of the controller's second burst
 * (TS-0006 4.2): the previous packet's + 1 is a running counter; else the
 * first burst's number (0 or 1) is the number each burst starts with, also
 * when this one's first packets are missing. A first burst that started at
 * another number (the capture started within a burst) leaves it to this
 * one: 0 or 1, else a running counter. */
static void
burst_learn_numbering(eglink_burst_t *b, guint16 pn)
{
    guint16 from = b->first_start <= 1 ? b->first_start : pn;

    if (b->numbering != VRPO_NUM_UNKNOWN || !b->have_prev)
        return;
    if (pn == (guint16)(b->prev_number + 1))
        b->numbering = VRPO_NUM_RUNNING;
    else if (from == 0)
        b->numbering = VRPO_NUM_FROM0;
    else if (from == 1)
        b->numbering = VRPO_NUM_FROM1;
    else
        b->numbering = VRPO_NUM_RUNNING;
}

/* A number that breaks the numbering learned (TS-0006 4.2: incremented by
 * one for each packet): a repeat, a step back, or a gap that no lost packet
 * explains (the serials are in sequence). */
static void
burst_check_number(const eglink_burst_t *b, eglink_frame_t *fd, guint16 pn, guint16 expected)
{
    if (pn == expected || !b->have_prev)
        return;
    if (pn == b->prev_number)
        add_finding(fd, FND_VRPO_NUMBER, b->prev_frame, expected, VRPO_BREAK_REPEAT);
    else if ((guint16)(pn - expected) >= 0x8000 || pn < expected)
        add_finding(fd, FND_VRPO_NUMBER, b->prev_frame, expected, VRPO_BREAK_BACK);
    else if (fd->serial_status != SERIAL_LOST)
        add_finding(fd, FND_VRPO_NUMBER, b->prev_frame, expected, VRPO_BREAK_GAP);
}

/* TS-0006 5.1.2: the bursts come every 50 to 200 ms (recommended); longer
 * than the VRPO gap threshold is the gap error instead. */
static void
burst_check_interval(eglink_burst_t *b, eglink_frame_t *fd, packet_info *pinfo)
{
    gint64 iv;

    if (b->have_start_ts) {
        iv = ns_between(&pinfo->abs_ts, &b->start_ts);
        if ((iv < ms_to_ns(EGLINK_VRPO_INTERVAL_MIN_MS) || iv > ms_to_ns(EGLINK_VRPO_INTERVAL_MAX_MS)) &&
            iv <= ms_to_ns(eglink_pref_vrpo_gap_ms))
            add_finding(fd, FND_VRPO_INTERVAL, 0, 0, iv);
    }
    b->have_start_ts = TRUE;
    b->start_ts = pinfo->abs_ts;
}

/* TS-0006 5.1.2: the packets of a split burst are sent without delay. */
static void
burst_check_spread(const eglink_burst_t *b, eglink_frame_t *fd, packet_info *pinfo)
{
    gint64 delay = ns_between(&pinfo->abs_ts, &b->prev_ts);

    if (delay > ms_to_ns(eglink_pref_burst_spread_ms))
        add_finding(fd, FND_BURST_SPREAD, b->prev_frame, 0, delay);
}

static void
burst_open(eglink_burst_t *b, eglink_frame_t *fd, packet_info *pinfo, const eglink_info_t *info)
{
    int len = info->periodic_len;
    guint16 pn = info->packet_number;

    b->open = TRUE;
    b->broken = FALSE;
    b->quiet = FALSE;
    b->first_frame = pinfo->num;
    b->start = pn;
    b->next = (guint16)(pn + 1);
    b->bytes = (guint32)len;
    if (burst_ends_here(b, len)) {
        /* One packet: nothing to reassemble. */
        burst_check_size(b, fd);
        fd->flags |= FF_BURST_ONE;
        b->open = FALSE;
        return;
    }
    if (info->cut) {
        /* its data is not all in the capture: no reassembly */
        b->broken = b->missing_cut = TRUE;
        b->missing = pn;
        b->id = 0;
        return;
    }
    b->id = ++eglink_burst_count;
    fd->burst_id = b->id;
    fd->burst_seq = 0;
}

/* A burst whose first packets were not captured (or lost), or the tail of
 * one that ended at a short packet (quiet). */
static void
burst_open_broken(eglink_burst_t *b, packet_info *pinfo, guint16 missing, gboolean quiet)
{
    b->open = TRUE;
    b->broken = TRUE;
    b->quiet = quiet;
    b->missing_cut = FALSE;
    b->missing = missing;
    b->id = 0;
    b->first_frame = pinfo->num;
    b->bytes = 0;
}

/* A packet of the open burst after its first one. */
static void
burst_continue(eglink_burst_t *b, eglink_frame_t *fd, const eglink_info_t *info)
{
    int len = info->periodic_len;
    guint16 pn = info->packet_number;

    if (!b->broken && pn != b->next) {
        b->broken = TRUE;
        b->missing_cut = FALSE;
        b->missing = b->next;
    } else if (!b->broken && info->cut) {
        b->broken = b->missing_cut = TRUE;
        b->missing = pn;
    }
    b->next = (guint16)(pn + 1);
    b->bytes += (guint32)len;
    if (!b->broken) {
        fd->burst_id = b->id;
        fd->burst_seq = (guint16)(pn - b->start);
    }
    if (burst_ends_here(b, len)) {
        if (b->quiet) {
            /* said already */
        } else if (b->broken) {
            add_finding(fd, FND_BURST_INCOMPLETE, b->first_frame,
                        b->missing | (b->missing_cut ? EGLINK_BURST_CUT : 0), 0);
        } else {
            fd->flags |= FF_BURST_LAST;
            burst_check_size(b, fd);
        }
        b->open = FALSE;
    }
}

/* VRPO packet numbers count up by one for each packet (TS-0006 4.2), from 0
 * or from 1 in each burst, or on across bursts (learned per controller); all
 * packets of a burst but the last carry 488 bytes. A burst ends at a short
 * packet, when it reaches the configured periodic data size, or when the
 * next burst starts. */
void
track_burst(eglink_burst_t *b, eglink_frame_t *fd, packet_info *pinfo, const eglink_info_t *info)
{
    guint16 pn = info->packet_number;
    gint32 start;

    if (fd->serial_status == SERIAL_RESTART) {
        /* a controller restarting may number afresh */
        burst_close_open(b, fd);
        b->numbering = VRPO_NUM_UNKNOWN;
        b->have_prev = FALSE;
    }
    if (b->open && b->have_prev && pn == (guint16)(b->prev_number + 1)) {
        burst_check_spread(b, fd, pinfo);
        burst_continue(b, fd, info);
    } else if (!b->open && b->have_prev && pn == (guint16)(b->prev_number + 1) &&
               b->prev_len < EGLINK_VRPO_FRAGMENT_MAX &&
               (b->numbering == VRPO_NUM_FROM0 || b->numbering == VRPO_NUM_FROM1) &&
               ns_between(&pinfo->abs_ts, &b->prev_ts) <= ms_to_ns(eglink_pref_burst_spread_ms)) {
        /* The short packet before was not the last of its burst. */
        add_finding(fd, FND_VRPO_NOT_FULL, b->prev_frame, b->prev_number | (b->prev_len << 16), 0);
        burst_open_broken(b, pinfo, 0, TRUE);
        burst_continue(b, fd, info);
    } else {
        /* (within the first burst, only its first number again starts the second) */
        if (!b->open || (pn == b->first_start && pn <= 1))
            burst_learn_numbering(b, pn);
        start = burst_expected_start(b);
        if (b->open && (gint32)pn != start) {
            /* Within the open burst: a number out of sequence. */
            burst_check_number(b, fd, pn, (guint16)(b->prev_number + 1));
            burst_check_spread(b, fd, pinfo);
            burst_continue(b, fd, info);
        } else {
            burst_close_open(b, fd);
            if (start >= 0)
                burst_check_number(b, fd, pn, (guint16)start);
            if (!b->have_prev)
                b->first_start = pn;
            burst_check_interval(b, fd, pinfo);
            if (start >= 0 && b->numbering != VRPO_NUM_RUNNING && pn > start &&
                (guint16)(pn - start) < 0x100) {
                /* its first packets were not captured (or lost) */
                burst_open_broken(b, pinfo, (guint16)start, FALSE);
                b->start = (guint16)start;
                burst_continue(b, fd, info);
            } else {
                burst_open(b, fd, pinfo, info);
            }
        }
    }
    b->have_prev = TRUE;
    b->prev_number = pn;
    b->prev_frame = pinfo->num;
    b->prev_len = (guint32)MAX(info->periodic_len, 0);
    b->prev_ts = pinfo->abs_ts;
}

/* The BU origin handed to the machine data decoder with the periodic data:
 * the one show_device() names as eglink.analysis.bu_origin, 0 if none. */
static guint16
data_bu_origin(const eglink_frame_t *fd)
{
    if (fd->flags & FF_ORIGIN)
        return fd->bu_origin;
    if (!fd->bu && fd->ctrl && fd->ctrl->bu && fd->ctrl->bu->origin_known)
        return fd->ctrl->bu->origin;
    return 0;
}

static void
show_reassembled(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree, const eglink_info_t *info,
                 fragment_head *fh, guint16 bu_origin)
{
    tvbuff_t *next_tvb;
    proto_item *ti;

    next_tvb = process_reassembled_data(tvb, info->periodic_offset, pinfo,
                                        "Reassembled VRPO periodic data", fh, &eglink_frag_items,
                                        NULL, tree);
    if (!next_tvb)
        return;
    col_append_fstr(pinfo->cinfo, COL_INFO, " [Reassembled %u bytes]", tvb_reported_length(next_tvb));
    if (hf_eglink_periodic_data_id == -1)
        hf_eglink_periodic_data_id = proto_registrar_get_id_byname("eglink.periodic_data");
    if (hf_eglink_periodic_data_id != -1) {
        ti = proto_tree_add_item(tree, hf_eglink_periodic_data_id, next_tvb, 0, -1, ENC_NA);
        proto_item_append_text(ti, " (reassembled, %u bytes)", tvb_reported_length(next_tvb));
    }
    eglink_data_dissect(next_tvb, pinfo, tree, "vrpo", info->origin, bu_origin);
}

void
show_reassembly(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree, const eglink_info_t *info,
                const eglink_frame_t *fd)
{
    const eglink_finding_t *f;
    fragment_head *fh;

    if (info->type != EGLINK_TYPE_VRPO)
        return;
    /* A burst of one packet is complete as it is. */
    if (((fd->flags & FF_BURST_ONE) || (fd->serial_status == SERIAL_REPEAT && info->packet_number == 0)) &&
        !(fd->flags & FF_INVALID) && info->periodic_len > 0 &&
        tvb_bytes_exist(tvb, info->periodic_offset, info->periodic_len))
        eglink_data_dissect(tvb_new_subset_length(tvb, info->periodic_offset, info->periodic_len),
                            pinfo, tree, "vrpo", info->origin, data_bu_origin(fd));
    if (!eglink_pref_reassemble)
        return;
    /* A packet 0 that shows where the previous (all full) burst ended. */
    for (f = fd->findings; f; f = f->next) {
        if (f->kind == FND_BURST_DONE) {
            fh = fragment_end_seq_next(&eglink_reassembly_table, pinfo, f->value, NULL);
            show_reassembled(tvb, pinfo, tree, info, fh, data_bu_origin(fd));
        }
    }
    if (fd->burst_id && tvb_bytes_exist(tvb, info->periodic_offset, info->periodic_len)) {
        fh = fragment_add_seq_check(&eglink_reassembly_table, tvb, info->periodic_offset, pinfo,
                                    fd->burst_id, NULL, fd->burst_seq,
                                    (guint32)info->periodic_len, !(fd->flags & FF_BURST_LAST));
        show_reassembled(tvb, pinfo, tree, info, fh, data_bu_origin(fd));
    }
}

/* ---------------------------------------------------------------------- */

void
eglink_bursts_register(int proto)
{
    static hf_register_info hf[] = {
        { &hf_fragments,
          { "VRPO fragments", "eglink.fragments", FT_NONE, BASE_NONE, NULL, 0x0,
            "The VRPO packets of a split periodic output", HFILL } },
        { &hf_fragment,
          { "VRPO fragment", "eglink.fragment", FT_FRAMENUM, BASE_NONE, NULL, 0x0,
            "A VRPO packet of the burst", HFILL } },
        { &hf_fragment_overlap,
          { "Fragment overlap", "eglink.fragment.overlap", FT_BOOLEAN, BASE_NONE, NULL, 0x0,
            "Fragment overlaps with other fragments", HFILL } },
        { &hf_fragment_overlap_conflicts,
          { "Conflicting data in fragment overlap", "eglink.fragment.overlap.conflicts",
            FT_BOOLEAN, BASE_NONE, NULL, 0x0, "Overlapping fragments contain conflicting data",
            HFILL } },
        { &hf_fragment_multiple_tails,
          { "Multiple tail fragments found", "eglink.fragment.multiple_tails", FT_BOOLEAN,
            BASE_NONE, NULL, 0x0, "Several tails were found when reassembling", HFILL } },
        { &hf_fragment_too_long_fragment,
          { "Fragment too long", "eglink.fragment.too_long_fragment", FT_BOOLEAN, BASE_NONE,
            NULL, 0x0, "Fragment contained data past the end of the burst", HFILL } },
        { &hf_fragment_error,
          { "Reassembly error", "eglink.fragment.error", FT_FRAMENUM, BASE_NONE, NULL, 0x0,
            "Reassembly error due to illegal fragments", HFILL } },
        { &hf_fragment_count,
          { "Fragment count", "eglink.fragment.count", FT_UINT32, BASE_DEC, NULL, 0x0,
            "Number of VRPO packets in the burst", HFILL } },
        { &hf_reassembled_in,
          { "Reassembled in", "eglink.reassembled_in", FT_FRAMENUM, BASE_NONE, NULL, 0x0,
            "Frame in which the burst's periodic data is reassembled", HFILL } },
        { &hf_reassembled_length,
          { "Reassembled periodic data length", "eglink.reassembled.length", FT_UINT32, BASE_DEC,
            NULL, 0x0, "Total periodic data of the burst, in bytes", HFILL } },
    };
    static gint *ett[] = {
        &ett_fragment,
        &ett_fragments,
    };

    proto_register_field_array(proto, hf, array_length(hf));
    proto_register_subtree_array(ett, array_length(ett));
    reassembly_table_register(&eglink_reassembly_table, &addresses_ports_reassembly_table_functions);
}
