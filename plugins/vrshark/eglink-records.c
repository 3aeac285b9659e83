/* eglink-records.c
 * The EG-Link analysis's records by frame number, kept for the passes after
 * the first (twin: lua/vrshark/eglink_records.luam). Most frames need only a
 * 16-byte slot in pages indexed by frame number; a frame with findings, a
 * command link or a reassembly ID keeps its full record with
 * p_add_proto_data. Also the findings list hung off a record, and what
 * "tshark -2 -R" does to frame numbers (eglink_frame_renumbered()).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "eglink-shared.h"

#include "eglink-compat.h"

#include <epan/proto_data.h>

static int proto_eglink = -1;

/* What most frames store: 12 bytes in a table indexed by frame number. Only
 * the first EG-Link layer of a frame has a slot; the record of any other
 * layer, and of a frame whose full record does not fit, is stored with
 * p_add_proto_data (FF_FULL). The expected serial is not kept: it is the
 * packet's own serial after a packet in sequence (SERIAL_OK) and 0 before
 * the first; a frame after a gap keeps its full record. */
typedef struct {
    guint32 unit;               /* BU index, or SLOT_CTRL | controller index */
    guint32 delta_ns;           /* delta_ns of the full record when FF_DELTA */
    guint16 flags;              /* FF_*, the layer (slot_layer_bits), serial_status << FF_STATUS_SHIFT */
    guint16 bu_origin;
} eglink_slot_t;

#define SLOT_CTRL        0x80000000u
/* pinfo->curr_layer_num, 1 to 8, as 0 to 7 in flags bits 10, 11 and 15 */
#define SLOT_LAYER_MAX   8

#define EGLINK_SLOT_PAGE_BITS 12
#define EGLINK_SLOT_PAGE_SIZE (1u << EGLINK_SLOT_PAGE_BITS)

/* The first-pass frame seen last (number, file offset). tshark -2 -R keeps
 * only the frames that pass the read filter on the first pass and numbers
 * each frame one more than the count kept so far: a dropped frame gives its
 * number to the next one. A first-pass frame with the number of the one
 * before it (at another file offset) clears that frame's slot; elsewhere
 * numbers never repeat. */
static guint32 eglink_fp_num;
static gint64 eglink_fp_off;
/* File scope: the pages of slots by frame number. */
static eglink_slot_t **eglink_slot_pages;
static guint32 eglink_slot_page_count;

static guint16
slot_layer_bits(int layer)
{
    guint v = (guint)(layer - 1);

    return (guint16)(((v & 3) << FF_LAYER_SHIFT) | ((v & 4) << 13));
}

static int
slot_layer(guint16 flags)
{
    return (int)(((flags >> FF_LAYER_SHIFT) & 3) | ((flags >> 13) & 4)) + 1;
}

void
eglink_records_init(void)
{
    eglink_fp_num = 0;
    eglink_fp_off = -1;
    eglink_slot_pages = NULL;
    eglink_slot_page_count = 0;
}

void
eglink_records_register(int proto)
{
    proto_eglink = proto;
}

/* The slot of a frame; NULL when its page does not exist and !create. */
static eglink_slot_t *
eglink_slot(guint32 frame, gboolean create)
{
    guint32 page = frame >> EGLINK_SLOT_PAGE_BITS;

    if (page >= eglink_slot_page_count) {
        guint32 count = eglink_slot_page_count ? eglink_slot_page_count : 64;

        if (!create)
            return NULL;
        while (count <= page)
            count *= 2;
        if (eglink_slot_pages)
            eglink_slot_pages = (eglink_slot_t **)wmem_realloc(wmem_file_scope(), eglink_slot_pages,
                                                                count * sizeof(eglink_slot_t *));
        else
            eglink_slot_pages = wmem_alloc_array(wmem_file_scope(), eglink_slot_t *, count);
        memset(eglink_slot_pages + eglink_slot_page_count, 0,
               (count - eglink_slot_page_count) * sizeof(eglink_slot_t *));
        eglink_slot_page_count = count;
    }
    if (!eglink_slot_pages[page]) {
        if (!create)
            return NULL;
        eglink_slot_pages[page] = wmem_alloc0_array(wmem_file_scope(), eglink_slot_t,
                                                    EGLINK_SLOT_PAGE_SIZE);
    }
    return &eglink_slot_pages[page][frame & (EGLINK_SLOT_PAGE_SIZE - 1)];
}

/* The expected serial a slot stands for (see eglink_slot_t). */
static guint16
slot_expected_serial(guint8 serial_status, guint16 serial)
{
    return serial_status == SERIAL_OK ? serial : 0;
}

static gboolean
eglink_frame_is_compact(const eglink_frame_t *fd, int layer, guint16 serial)
{
    return !fd->findings && !fd->cmd && !fd->burst_id &&
           (!(fd->flags & FF_DELTA) || (fd->delta_ns >= 0 && fd->delta_ns <= G_MAXUINT32)) &&
           fd->expected_serial == slot_expected_serial(fd->serial_status, serial) &&
           layer >= 1 && layer <= SLOT_LAYER_MAX;
}

/* Stores the record of the current layer (of a packet with this serial),
 * computed on the first pass: the full record as stored, NULL for a compact one. */
eglink_frame_t *
eglink_frame_store(packet_info *pinfo, guint32 key, guint16 serial, const eglink_frame_t *fd)
{
    eglink_frame_t *stored;
    eglink_slot_t *slot = eglink_slot(pinfo->num, TRUE);
    int layer = pinfo->curr_layer_num;

    if (!(slot->flags & FF_USED)) {
        if (eglink_frame_is_compact(fd, layer, serial)) {
            slot->flags = (guint16)(FF_USED | slot_layer_bits(layer) | (fd->flags & FF_FLAGS_MASK) |
                                    (fd->serial_status << FF_STATUS_SHIFT));
            slot->unit = fd->ctrl ? (SLOT_CTRL | fd->ctrl->index) : fd->bu->index;
            slot->delta_ns = (fd->flags & FF_DELTA) ? (guint32)fd->delta_ns : 0;
            slot->bu_origin = fd->bu_origin;
            return NULL;
        }
        /* (the layer is not kept: a full record is looked up by its key) */
        slot->flags = FF_USED | FF_FULL;
    }
    stored = (eglink_frame_t *)wmem_memdup(wmem_file_scope(), fd, sizeof(*fd));
    p_add_proto_data(wmem_file_scope(), pinfo, proto_eglink, key, stored);
    return stored;
}

/* The record of the current layer (of a packet with this serial), or NULL
 * if it has none (yet). A compact one is expanded into *buf. */
const eglink_frame_t *
eglink_frame_fetch(packet_info *pinfo, guint32 key, guint16 serial, eglink_frame_t *buf)
{
    const eglink_slot_t *slot = eglink_slot(pinfo->num, FALSE);

    if (slot && (slot->flags & FF_USED) && !(slot->flags & FF_FULL) &&
        slot_layer(slot->flags) == pinfo->curr_layer_num) {
        memset(buf, 0, sizeof(*buf));
        buf->flags = slot->flags & FF_FLAGS_MASK;
        if (slot->unit & SLOT_CTRL) {
            buf->ctrl = *(eglink_ctrl_t **)wmem_array_index(eglink_ctrl_by_index, slot->unit & ~SLOT_CTRL);
            /* (a controller packet with a BU origin: joined for being alone) */
            if (buf->flags & FF_ORIGIN)
                buf->bu = buf->ctrl->alone_bu;
        } else {
            buf->bu = *(eglink_bu_t **)wmem_array_index(eglink_bu_by_index, slot->unit);
        }
        buf->delta_ns = slot->delta_ns;
        buf->serial_status = (guint8)((slot->flags >> FF_STATUS_SHIFT) & 0x7);
        buf->expected_serial = slot_expected_serial(buf->serial_status, serial);
        buf->bu_origin = slot->bu_origin;
        return buf;
    }
    if (!slot || !(slot->flags & FF_USED))
        return NULL;
    return (const eglink_frame_t *)p_get_proto_data(wmem_file_scope(), pinfo, proto_eglink, key);
}

/* tshark -2 -R: a first-pass frame with the number of the one before it
 * (at another file offset) clears that frame's slot. */
void
eglink_frame_renumbered(packet_info *pinfo)
{
    if (pinfo->num == eglink_fp_num && pinfo->fd->file_off != eglink_fp_off) {
        eglink_slot_t *slot = eglink_slot(pinfo->num, FALSE);

        if (slot)
            memset(slot, 0, sizeof(*slot));
    }
    eglink_fp_num = pinfo->num;
    eglink_fp_off = pinfo->fd->file_off;
}

void
add_finding(eglink_frame_t *fd, eglink_finding_kind_t kind, guint32 frame, guint32 value, gint64 ns)
{
    eglink_finding_t *f = wmem_new0(wmem_file_scope(), eglink_finding_t);
    eglink_finding_t **tail = &fd->findings;

    f->kind = (guint8)kind;
    f->frame = frame;
    f->value = value;
    f->ns = ns;
    while (*tail)
        tail = &(*tail)->next;
    *tail = f;
}

const eglink_finding_t *
find_finding(const eglink_frame_t *fd, eglink_finding_kind_t kind)
{
    const eglink_finding_t *f;

    for (f = fd->findings; f; f = f->next)
        if (f->kind == kind)
            return f;
    return NULL;
}
