/* eglink-analysis.c
 * EG-Link conversation analysis: per-BU tracking of serial numbers and
 * periodic intervals, command/acknowledge links with retransmissions and
 * timeouts, reassembly of split VRPO bursts, and the "eglink" tap.
 *
 * Everything is computed on the first pass, in frame order, and stored per
 * frame in file scope, so a single pass, "tshark -2" and clicking around in
 * the GUI show the same findings (only a failed command's is placed
 * differently, below). Most frames need only a 16-byte record in a
 * table indexed by frame number; a frame with findings, a command link or a
 * reassembly ID keeps its full record with p_add_proto_data. A finding that depends
 * on time passing (a missing VRPI/VRPO) is reported on the first packet of
 * the BU that arrives after the deadline: that is the earliest packet at
 * which a one-pass reader knows it. An unacknowledged command is reported
 * on the command itself, with a forward link to that packet (second pass and
 * GUI); the packet gets a note naming the command. In one pass the command
 * is behind the reader already, so that packet carries the command's
 * warning instead (show_failed()).
 *
 * Which packets belong to one BU: the BU sends VRPI/VRCI/VRAI to its input
 * port, the machine controller sends VRPO/VRCO/VRAO to the input port + 2,
 * both usually to the same multicast group. Packets meet on a channel:
 *   (multicast group, input port)                      for multicast, or
 *   (the two unicast addresses, unordered, input port)  for unicast,
 * where the input port is the destination port of a BU packet and the
 * destination port - 2 of a controller packet. Every BU ships with the same
 * group and ports, so one channel may carry several BUs: on it, a BU is
 * its origin and source address, a controller its source address (its
 * packets carry origin 0). Each sender has its own serials, periodic
 * interval and commands. A controller is joined to its BU by the command
 * IDs acknowledged between them (a VRAO for a BU's VRCI, a VRAI for the
 * controller's VRCO), or while it is the only one beside the only BU of the
 * channel; until then its packets are analysed on their own.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "eglink-analysis.h"

#include "eglink-compat.h"

#include <epan/expert.h>
#include <epan/proto_data.h>
#include <epan/reassemble.h>
#include <epan/tap.h>
#include <epan/to_str.h>

/* p_add_proto_data key: one record per EG-Link layer of a frame. */
#define EGLINK_ANALYSIS_KEY_BASE 0x45410000u
/* Commands remembered per direction and BU (bounded: oldest replaced). */
#define EGLINK_CMD_SLOTS 8
/* A serial this far behind the last one is a restart, not a repeat, even
 * with no other sign of one (track_serial()). */
#define EGLINK_SERIAL_REPEAT_WINDOW 1024
/* Packets of a sender with a bad CRC or size remembered until its next valid one. */
#define EGLINK_BAD_SLOTS 4
/* Time going back less than this between EG-Link packets is taken as packets
 * of two interfaces a little out of order (no finding, no time below 0);
 * more is a clock step. */
#define EGLINK_CLOCK_JITTER_NS 1000000

static int proto_eglink = -1;
static int eglink_tap = -1;
static int hf_eglink_periodic_data_id = -1;     /* looked up by name: eglink.periodic_data */

static int hf_analysis = -1;
static int hf_bu_stream = -1;
static int hf_bu_origin = -1;
static int hf_device = -1;
static int hf_joined_alone = -1;
static int hf_expected_serial = -1;
static int hf_lost = -1;
static int hf_repeat_of = -1;
static int hf_time_since_prev_vrpi = -1;
static int hf_time_since_prev_vrpo = -1;
static int hf_retransmission_of = -1;
static int hf_ack_in = -1;
static int hf_ack_to = -1;
static int hf_ack_time = -1;
static int hf_failed_command = -1;
static int hf_deadline_in = -1;
static int hf_incomplete_burst = -1;
static int hf_last_vrpi = -1;
static int hf_last_vrpo = -1;
static int hf_corrupted_in = -1;
static int hf_expected_port = -1;
static int hf_time_backwards_after = -1;

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

static gint ett_analysis = -1;
static gint ett_fragment = -1;
static gint ett_fragments = -1;

static expert_field ei_serial_gap = EI_INIT;
static expert_field ei_serial_repeat = EI_INIT;
static expert_field ei_serial_restart = EI_INIT;
static expert_field ei_vrpi_gap = EI_INIT;
static expert_field ei_vrpo_gap = EI_INIT;
static expert_field ei_vrpi_missing = EI_INIT;
static expert_field ei_vrpo_missing = EI_INIT;
static expert_field ei_retransmission = EI_INIT;
static expert_field ei_vrci_unacked = EI_INIT;
static expert_field ei_vrco_unacked = EI_INIT;
static expert_field ei_vrci_deadline = EI_INIT;
static expert_field ei_vrco_deadline = EI_INIT;
static expert_field ei_late_ack = EI_INIT;
static expert_field ei_unknown_ack = EI_INIT;
static expert_field ei_bu_state_changed = EI_INIT;
static expert_field ei_origin_changed = EI_INIT;
static expert_field ei_burst_incomplete = EI_INIT;
static expert_field ei_burst_size = EI_INIT;
static expert_field ei_shared_group = EI_INIT;
static expert_field ei_command = EI_INIT;
static expert_field ei_ack = EI_INIT;
static expert_field ei_serial_corrupted = EI_INIT;
static expert_field ei_wrong_port = EI_INIT;
static expert_field ei_time_backwards = EI_INIT;
static expert_field ei_vrpo_number = EI_INIT;
static expert_field ei_vrpo_interval = EI_INIT;
static expert_field ei_burst_spread = EI_INIT;
static expert_field ei_vrpo_not_full = EI_INIT;
static expert_field ei_resend_interval = EI_INIT;
static expert_field ei_not_resent = EI_INIT;
static expert_field ei_resent_after_ack = EI_INIT;
static expert_field ei_resent_after_deadline = EI_INIT;
static expert_field ei_command_id_sequence = EI_INIT;
static expert_field ei_revision_ignored = EI_INIT;
static expert_field ei_not_joined = EI_INIT;
static expert_field ei_join_withdrawn = EI_INIT;

/* Preferences */
static guint pref_vrpi_gap_ms = 500;
static guint pref_vrpo_gap_ms = 2000;
static guint pref_vrci_ack_timeout_ms = 2000;
static guint pref_vrco_ack_timeout_ms = 2000;
static guint pref_periodic_size = 0;
static eglink_pref_bool_t pref_reassemble = TRUE;
/* TS-0006 5.1.3, 5.1.4: commands are resent every 100 ms until acknowledged. */
#define EGLINK_RESEND_INTERVAL_MS 100
static guint pref_resend_tolerance_ms = 20;
/* TS-0006 5.1.2: VRPO every 50 to 200 ms (recommended); a split burst without delay. */
#define EGLINK_VRPO_INTERVAL_MIN_MS 50
#define EGLINK_VRPO_INTERVAL_MAX_MS 200
static guint pref_burst_spread_ms = 10;

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

/* One command (VRCI or VRCO) with all its transmissions. */
typedef struct {
    nstime_t first_ts;
    nstime_t last_ts;           /* latest transmission */
    guint32 first_frame;
    guint32 last_frame;         /* latest transmission */
    guint32 ack_frame;          /* first acknowledgement, 0 if none (yet) */
    guint32 deadline_frame;     /* first packet seen after the deadline passed unacknowledged */
    guint16 command_id;
    guint8 dir;                 /* EGLINK_DIR_IN: VRCI, EGLINK_DIR_OUT: VRCO */
    guint8 failed;              /* the deadline passed unacknowledged */
    guint8 clock_step;          /* the clock stepped back while it waited: its deadline counts
                                 * from the step, its acknowledgement time is not known */
    guint8 resend_reported;     /* a resend that did not come was flagged (or cannot be timed) */
} eglink_cmd_t;

/* Where the packets of BUs and controllers meet: a multicast group and the
 * BU's input port, or a unicast address pair and the input port. */
typedef struct {
    address a;                  /* multicast group, or the lower unicast address */
    address b;                  /* AT_NONE for multicast, else the higher address */
    guint32 port;               /* the BU's input port */
} eglink_chan_key_t;

typedef struct eglink_bu eglink_bu_t;
typedef struct eglink_ctrl eglink_ctrl_t;
typedef struct eglink_chan eglink_chan_t;

/* The channels of one multicast group or unicast address pair, any port. */
typedef struct {
    eglink_chan_t *chans;
} eglink_group_t;

struct eglink_chan {
    const char *where;          /* "239.255.42.20 port 5825" */
    guint32 port;               /* the BU's input port */
    gboolean own_port;          /* a controller's port that fits no BU seen (no input port) */
    eglink_chan_t *group_next;  /* in its group's chans */
    eglink_bu_t *bus;           /* the BUs seen on it, newest first */
    eglink_ctrl_t *ctrls;       /* the machine controllers seen on it, newest first */
    guint n_bus;
    guint n_ctrls;
};

/* What one sender (a BU or a machine controller) tracks of its own packets:
 * serials, its periodic packets (VRPI of a BU, VRPO of a controller) and
 * the commands it sends (VRCI of a BU, VRCO of a controller). */
typedef struct {
    gboolean have_serial;
    guint16 last_serial;
    guint32 last_serial_frame;

    guint32 last_periodic_frame;    /* 0: none yet */
    nstime_t last_periodic_ts;
    gboolean periodic_missing_reported;

    eglink_cmd_t *cmds[EGLINK_CMD_SLOTS];
    guint cmd_next;
    gboolean have_cmd_id;       /* the Command ID of its latest new command ... */
    guint16 last_cmd_id;        /* ... (TS-0006 4.3, 4.5: numbered sequentially) */

    gboolean shared_reported;   /* the shared-group warning was given */
    gboolean clock_restart;     /* the clock stepped back: no interval to the next periodic packet */

    /* Its packets with a bad CRC or size since its last valid one: a serial
     * gap they fill is no loss. */
    guint32 bad_frame[EGLINK_BAD_SLOTS];
    guint16 bad_serial[EGLINK_BAD_SLOTS];
    guint8 bad_crc[EGLINK_BAD_SLOTS];   /* TRUE: bad CRC, FALSE: wrong size */
    guint n_bad;
} eglink_sender_t;

/* A BU: its origin and its address, on one channel. */
struct eglink_bu {
    eglink_sender_t s;
    guint32 index;              /* BU stream number, from 0 in order of appearance */
    const char *name;           /* "BU 0x1001 (10.0.0.1)" */
    eglink_chan_t *chan;
    address addr;
    guint16 origin;
    gboolean origin_known;      /* origin is from a valid packet (not one with a bad CRC) */
    gboolean have_bu_state;
    guint8 bu_state;
    nstime_t state_since;       /* the VRPI that first reported bu_state */
    gboolean state_since_step;  /* ... or the clock step after it: its length is not known */
    eglink_bu_t *next;          /* in chan->bus */
};

/* How a controller numbers its VRPO packets (TS-0006 4.2 only says "incremented
 * by one for each packet"): each burst from 0, each burst from 1, or one
 * counter running on across bursts. Learned from the start of its second burst. */
typedef enum {
    VRPO_NUM_UNKNOWN,
    VRPO_NUM_FROM0,
    VRPO_NUM_FROM1,
    VRPO_NUM_RUNNING
} eglink_vrpo_numbering_t;

/* A split VRPO burst of one controller, and its VRPO numbering. */
typedef struct {
    gboolean open;              /* a burst whose end is not seen yet */
    gboolean broken;            /* ... with a packet missing: it cannot complete */
    gboolean quiet;             /* ... the tail of one already ended: not reported incomplete */
    guint32 id;                 /* its reassembly ID (0 when broken from the start) */
    guint32 first_frame;
    guint16 start;              /* packet number of its first packet */
    guint16 next;               /* packet number expected next */
    guint16 missing;            /* first missing packet number */
    gboolean missing_cut;       /* ... in the capture, cut by its snap length */
    guint32 bytes;

    guint8 numbering;           /* eglink_vrpo_numbering_t */
    guint16 first_start;        /* number of the first burst's first packet (numbering unknown) */
    gboolean have_prev;         /* the previous VRPO of the controller: */
    guint16 prev_number;
    guint32 prev_frame;
    guint32 prev_len;
    nstime_t prev_ts;
    gboolean have_start_ts;     /* the first packet of its previous burst (VRPO interval) */
    nstime_t start_ts;
} eglink_burst_t;

/* An acknowledgement a controller sent on a port of its own, before it
 * turned up with a BU: matched then (see eglink_ctrl_adopt()). */
typedef struct {
    struct eglink_frame *fd;    /* its record, as stored */
    nstime_t ts;
    guint32 frame;
    guint16 command_id;
} eglink_orphan_ack_t;

#define EGLINK_ORPHAN_ACKS 4

/* A machine controller: its address, on one channel; joined to the BU it
 * talks to once that is known. */
struct eglink_ctrl {
    eglink_sender_t s;
    guint32 index;              /* from 0 in order of appearance */
    const char *name;           /* "Controller 10.0.0.11 (BU not known)" */
    eglink_chan_t *chan;
    address addr;
    eglink_bu_t *bu;            /* its BU, NULL while not known */
    gboolean joined_by_ack;     /* ... known from a command it or the BU acknowledged */
    eglink_bu_t *alone_bu;      /* the BU it was joined to for being alone with it */
    guint32 withdrawn_frame;    /* where that stopped holding (a second BU or controller), 0: never */
    gboolean adopted;           /* first seen on a port of its own, then with this channel's BU */
    eglink_orphan_ack_t orphan_acks[EGLINK_ORPHAN_ACKS];
    guint n_orphan_acks;
    eglink_burst_t burst;
    eglink_ctrl_t *next;        /* in chan->ctrls */
};

/* Findings that only some frames have; a list hung off the frame record. */
typedef enum {
    FND_REPEAT,                 /* frame: earlier copy (0 unknown), value: last serial */
    FND_RESTART,                /* value: last serial */
    FND_ORIGIN,                 /* value: previous origin */
    FND_BU_STATE,               /* value: previous BU state */
    FND_VRPI_GAP,               /* frame: previous VRPI */
    FND_VRPO_GAP,               /* frame: previous VRPO */
    FND_VRPI_MISSING,           /* frame: last VRPI */
    FND_VRPO_MISSING,           /* frame: last VRPO */
    FND_FAILED_VRCI,            /* frame: first transmission, value: command ID, ns: age */
    FND_FAILED_VRCO,
    FND_LATE_ACK,               /* frame: first transmission, value: command ID */
    FND_UNKNOWN_ACK,            /* value: command ID */
    FND_BURST_DONE,             /* value: reassembly ID of the previous burst it completes */
    FND_BURST_INCOMPLETE,       /* frame: first packet of the burst, value: missing packet number */
    FND_BURST_SIZE,             /* value: bytes in the burst, ns: configured size */
    FND_SHARED_GROUP,           /* value: BUs on the channel, ns: controllers on it */
    FND_CORRUPTED,              /* frame: a packet of the serial gap that failed its check,
                                 * value: its serial | EGLINK_CORRUPTED_CRC */
    FND_WRONG_PORT,             /* value: the port it belongs on */
    FND_TIME_BACKWARDS,         /* frame: the EG-Link packet before, ns: how far back */
    FND_VRPO_NUMBER,            /* frame: previous VRPO, value: number expected, ns: VRPO_BREAK_* */
    FND_VRPO_INTERVAL,          /* ns: time since the previous burst's first packet */
    FND_BURST_SPREAD,           /* frame: previous packet of the burst, ns: delay after it */
    FND_VRPO_NOT_FULL,          /* frame: the short packet, value: its number | its bytes << 16 */
    FND_RESEND_INTERVAL,        /* frame: previous transmission, value: command ID | dir << 16, ns */
    FND_NOT_RESENT,             /* frame: latest transmission, value: command ID | dir << 16, ns */
    FND_RESENT_AFTER_ACK,       /* frame: the acknowledgement, value: command ID | dir << 16 */
    FND_RESENT_AFTER_DEADLINE,  /* frame: first transmission, value: command ID | dir << 16 */
    FND_CMD_ID_SEQUENCE,        /* value: command ID expected | dir << 16, ns: previous ID */
    FND_REVISION,               /* value: the header revision */
    FND_JOIN_WITHDRAWN          /* value: the controller's index, ns: 1 for a second BU, 0 controller */
} eglink_finding_kind_t;

/* FND_VRPO_NUMBER: how the numbering broke */
#define VRPO_BREAK_GAP      0
#define VRPO_BREAK_REPEAT   1
#define VRPO_BREAK_BACK     2

#define EGLINK_CORRUPTED_CRC    0x10000u    /* FND_CORRUPTED: a bad CRC (else a wrong size) */
#define EGLINK_BURST_CUT        0x10000u    /* FND_BURST_INCOMPLETE: the packet is cut, not missing */

typedef struct eglink_finding {
    struct eglink_finding *next;
    gint64 ns;
    guint32 frame;
    guint32 value;
    guint8 kind;
} eglink_finding_t;

typedef enum {
    SERIAL_FIRST,               /* first packet of this sender */
    SERIAL_OK,
    SERIAL_LOST,                /* packets missing before this one */
    SERIAL_REPEAT,              /* already seen (or older): ignored by the analysis */
    SERIAL_RESTART              /* far behind the last one: the sender restarted */
} eglink_serial_status_t;

#define FF_INVALID      0x0001  /* CRC or size check failed: not analysed */
#define FF_ORIGIN       0x0002  /* bu_origin is known */
#define FF_DELTA        0x0004  /* delta_ns is set */
#define FF_RETRANS      0x0008  /* VRCI/VRCO retransmission */
#define FF_FIRST_ACK    0x0010  /* first VRAO/VRAI of its command */
#define FF_BURST_ONE    0x0020  /* VRPO: a burst of one packet, complete as it is */
#define FF_REVISION     0x0080  /* header revision not 0: kept out of the analysis */
#define FF_BURST_LAST   0x0040  /* the last fragment of its burst */
#define FF_FLAGS_MASK   0x00FF  /* the flags above (the full record's) */
/* Only in the compact record: */
#define FF_USED         0x0100  /* the slot holds a frame's record */
#define FF_FULL         0x0200  /* the full record is in p_add_proto_data */
#define FF_LAYER_SHIFT  10      /* the layer in bits 10, 11 and 15 (below) */
#define FF_STATUS_SHIFT 12      /* serial_status in bits 12-14 */

/* The full record of one EG-Link layer of a frame. */
typedef struct eglink_frame {
    eglink_bu_t *bu;            /* the BU of the packet: its own, or the one its controller talks to */
    eglink_ctrl_t *ctrl;        /* a controller packet whose BU is not known (bu is NULL), or
                                 * joined to bu only for being alone with it (ctrl->alone_bu) */
    eglink_cmd_t *cmd;          /* VRCI/VRCO: its command; VRAO/VRAI: the one it acknowledges */
    eglink_finding_t *findings;
    gint64 delta_ns;            /* VRPI/VRPO: since the previous one; VRAO/VRAI: ack time */
    guint32 burst_id;           /* VRPO fragment: reassembly ID, 0 if not reassembled */
    guint16 burst_seq;          /* ... its place in the burst, from 0 */
    guint16 flags;
    guint16 expected_serial;
    guint16 bu_origin;
    guint8 serial_status;
} eglink_frame_t;

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

#define EGLINK_SLOT_PAGE_BITS 12
#define EGLINK_SLOT_PAGE_SIZE (1u << EGLINK_SLOT_PAGE_BITS)

static wmem_map_t *eglink_chans;
static wmem_map_t *eglink_groups;      /* group or address pair (port 0): eglink_group_t */
static guint32 eglink_burst_count;
/* The time of the latest EG-Link packet, to see the clock step back. */
static nstime_t eglink_last_ts;
static guint32 eglink_last_ts_frame;   /* 0: none yet */
/* The first-pass frame seen last (number, file offset). tshark -2 -R keeps
 * only the frames that pass the read filter on the first pass and numbers
 * each frame one more than the count kept so far: a dropped frame gives its
 * number to the next one. A first-pass frame with the number of the one
 * before it (at another file offset) clears that frame's slot; elsewhere
 * numbers never repeat. */
static guint32 eglink_fp_num;
static gint64 eglink_fp_off;
/* File scope: the BUs and controllers by index, and the pages of slots by frame number. */
static wmem_array_t *eglink_bu_by_index;
static wmem_array_t *eglink_ctrl_by_index;
static eglink_slot_t **eglink_slot_pages;
static guint32 eglink_slot_page_count;

/* ---------------------------------------------------------------------- */

static void
eglink_analysis_init(void)
{
    eglink_burst_count = 0;
    eglink_last_ts_frame = 0;
    eglink_fp_num = 0;
    eglink_fp_off = -1;
    nstime_set_zero(&eglink_last_ts);
    eglink_bu_by_index = NULL;
    eglink_ctrl_by_index = NULL;
    eglink_slot_pages = NULL;
    eglink_slot_page_count = 0;
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
static eglink_frame_t *
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
static const eglink_frame_t *
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

static gint64
ns_signed(const nstime_t *later, const nstime_t *earlier)
{
    nstime_t d;

    nstime_delta(&d, later, earlier);
    return (gint64)d.secs * 1000000000 + d.nsecs;
}

/* A time between two packets, never below 0: a clock step back restarts
 * every time the analysis measures (check_clock()), and packets a little
 * out of order count as simultaneous. */
static gint64
ns_between(const nstime_t *later, const nstime_t *earlier)
{
    return MAX(0, ns_signed(later, earlier));
}

static nstime_t
ns_to_nstime(gint64 ns)
{
    nstime_t t;

    t.secs = (time_t)(ns / 1000000000);
    t.nsecs = (int)(ns % 1000000000);
    return t;
}

static gint64
ms_to_ns(guint ms)
{
    return (gint64)ms * 1000000;
}

/* "0.812 s": rounded to the millisecond */
static const char *
ns_str(wmem_allocator_t *scope, gint64 ns)
{
    gint64 ms = (ns + 500000) / 1000000;     /* rounded to the millisecond */

    return wmem_strdup_printf(scope, "%" G_GINT64_FORMAT ".%03d s", ms / 1000, (int)(ms % 1000));
}

/* A time a finding compares with a limit (in ms): rounded to the
 * millisecond, or with as many more digits as it takes not to read as the
 * limit itself, which it is not ("0.2003 s" for a VRPO interval outside 50
 * to 200 ms). Rounding never carries a time across its limit, which has
 * no more digits. */
static const char *
ns_str_past(wmem_allocator_t *scope, gint64 ns, guint limit_ms)
{
    gint64 unit = 1000000, per_s = 1000, v = (ns + unit / 2) / unit;
    int digits = 3;

    while (unit > 1 && v * unit == ms_to_ns(limit_ms)) {
        unit /= 10;
        per_s *= 10;
        digits++;
        v = (ns + unit / 2) / unit;
    }
    return wmem_strdup_printf(scope, "%" G_GINT64_FORMAT ".%0*" G_GINT64_FORMAT " s",
                              v / per_s, digits, v % per_s);
}

static gboolean
eglink_is_input(eglink_type_t type)
{
    return type == EGLINK_TYPE_VRPI || type == EGLINK_TYPE_VRCI || type == EGLINK_TYPE_VRAI;
}

static gboolean
address_is_multicast(const address *addr)
{
    const guint8 *d = (const guint8 *)addr->data;

    if (addr->type == AT_IPv4 && addr->len == 4)
        return (d[0] & 0xF0) == 0xE0;
    if (addr->type == AT_IPv6 && addr->len == 16)
        return d[0] == 0xFF;
    return FALSE;
}

static guint
eglink_chan_hash(gconstpointer k)
{
    const eglink_chan_key_t *key = (const eglink_chan_key_t *)k;
    guint h = key->port;

    h = add_address_to_hash(h, &key->a);
    return add_address_to_hash(h, &key->b);
}

static gboolean
eglink_chan_equal(gconstpointer k1, gconstpointer k2)
{
    const eglink_chan_key_t *x = (const eglink_chan_key_t *)k1;
    const eglink_chan_key_t *y = (const eglink_chan_key_t *)k2;

    return x->port == y->port && addresses_equal(&x->a, &y->a) && addresses_equal(&x->b, &y->b);
}

/* The key of the channel on this port of the packet's group or address pair. */
static void
eglink_chan_key(packet_info *pinfo, guint32 port, eglink_chan_key_t *key)
{
    key->port = port;
    if (address_is_multicast(&pinfo->dst)) {
        key->a = pinfo->dst;
        clear_address(&key->b);
    } else if (cmp_address(&pinfo->src, &pinfo->dst) <= 0) {
        key->a = pinfo->src;
        key->b = pinfo->dst;
    } else {
        key->a = pinfo->dst;
        key->b = pinfo->src;
    }
}

static eglink_chan_key_t *
eglink_chan_key_copy(const eglink_chan_key_t *key)
{
    eglink_chan_key_t *stored = wmem_new(wmem_file_scope(), eglink_chan_key_t);

    copy_address_wmem(wmem_file_scope(), &stored->a, &key->a);
    copy_address_wmem(wmem_file_scope(), &stored->b, &key->b);
    stored->port = key->port;
    return stored;
}

/* The channels of the packet's group or address pair, on any port. */
static eglink_group_t *
eglink_group(packet_info *pinfo, gboolean create)
{
    eglink_chan_key_t key;
    eglink_group_t *group;

    eglink_chan_key(pinfo, 0, &key);
    group = (eglink_group_t *)wmem_map_lookup(eglink_groups, &key);
    if (!group && create) {
        group = wmem_new0(wmem_file_scope(), eglink_group_t);
        wmem_map_insert(eglink_groups, eglink_chan_key_copy(&key), group);
    }
    return group;
}

/* The channel of the packet's group or address pair on this input port;
 * NULL when there is none and !create. */
static eglink_chan_t *
eglink_chan_find(packet_info *pinfo, guint32 port, gboolean create)
{
    eglink_chan_key_t key;
    eglink_chan_t *chan;
    eglink_group_t *group;

    eglink_chan_key(pinfo, port, &key);
    chan = (eglink_chan_t *)wmem_map_lookup(eglink_chans, &key);
    if (chan || !create)
        return chan;

    chan = wmem_new0(wmem_file_scope(), eglink_chan_t);
    chan->port = port;
    if (key.b.type == AT_NONE)
        chan->where = wmem_strdup_printf(wmem_file_scope(), "%s port %u",
                                         address_to_str(pinfo->pool, &key.a), key.port);
    else
        chan->where = wmem_strdup_printf(wmem_file_scope(), "%s <-> %s port %u",
                                         address_to_str(pinfo->pool, &key.a),
                                         address_to_str(pinfo->pool, &key.b), key.port);
    wmem_map_insert(eglink_chans, eglink_chan_key_copy(&key), chan);
    group = eglink_group(pinfo, TRUE);
    chan->group_next = group->chans;
    group->chans = chan;
    return chan;
}

static gboolean
ctrl_on_chan(const eglink_chan_t *chan, const address *addr)
{
    const eglink_ctrl_t *ctrl;

    for (ctrl = chan->ctrls; ctrl; ctrl = ctrl->next)
        if (addresses_equal(&ctrl->addr, addr))
            return TRUE;
    return FALSE;
}

/* The channel of a controller packet. TS-0006 has the controller send to
 * the BU's input port + 2; a packet it sends to another port (the input
 * port, a wrong one) is still part of its conversation: the channel of its
 * group where it talks to a BU already, or the BU whose input port it went
 * to. *expected is then the port it belongs on (flagged), else 0. A port
 * that is neither (a controller on a port of its own, found by the
 * heuristic) is the output port of a channel of its own. */
static eglink_chan_t *
eglink_ctrl_chan(packet_info *pinfo, guint32 *expected)
{
    guint32 port = pinfo->destport;
    guint32 input = port >= 2 ? port - 2 : port;
    eglink_chan_t *chan = eglink_chan_find(pinfo, input, FALSE);
    eglink_chan_t *other;
    eglink_group_t *group;

    *expected = 0;
    if (chan && chan->n_bus)
        return chan;
    group = eglink_group(pinfo, FALSE);
    for (other = group ? group->chans : NULL; other; other = other->group_next) {
        if (other != chan && other->n_bus && ctrl_on_chan(other, &pinfo->src)) {
            *expected = other->port + 2;
            return other;
        }
    }
    other = eglink_chan_find(pinfo, port, FALSE);
    if ((other && other->n_bus) || (!eglink_is_input_port(input) && eglink_is_input_port(port))) {
        *expected = port + 2;
        return other ? other : eglink_chan_find(pinfo, port, TRUE);
    }
    if (!chan)
        chan = eglink_chan_find(pinfo, input, TRUE);
    if (!eglink_is_input_port(input))
        chan->own_port = TRUE;
    return chan;
}

/* The channel of a BU packet: its destination port, the input packet port
 * (TS-0006 2.2). One sent to an input port + 2, the output packet port,
 * belongs to that input port's channel, on the wrong port, as a controller
 * packet sent to the input port does: when a BU is seen there, or that port
 * is a configured input port and this one is not. */
static eglink_chan_t *
eglink_bu_chan(packet_info *pinfo, guint32 *expected)
{
    guint32 port = pinfo->destport;
    eglink_chan_t *chan = eglink_chan_find(pinfo, port, FALSE);
    eglink_chan_t *input;

    *expected = 0;
    if (port < 2 || (chan && chan->n_bus) || eglink_is_input_port(port))
        return chan ? chan : eglink_chan_find(pinfo, port, TRUE);
    input = eglink_chan_find(pinfo, port - 2, FALSE);
    if ((input && input->n_bus) || eglink_is_input_port(port - 2)) {
        *expected = port - 2;
        return input ? input : eglink_chan_find(pinfo, port - 2, TRUE);
    }
    return chan ? chan : eglink_chan_find(pinfo, port, TRUE);
}

/* Two BUs with the same origin and address on different ports or groups
 * get the port or group in their name, so that each has its own row in
 * the statistics. */
static const char *
eglink_bu_name(packet_info *pinfo, const eglink_chan_t *chan, guint16 origin)
{
    const char *name = wmem_strdup_printf(wmem_file_scope(), "BU 0x%04x (%s)", origin,
                                          address_to_str(pinfo->pool, &pinfo->src));
    guint i;

    for (i = 0; eglink_bu_by_index && i < wmem_array_get_count(eglink_bu_by_index); i++) {
        const eglink_bu_t *other = *(eglink_bu_t **)wmem_array_index(eglink_bu_by_index, i);
        if (strcmp(other->name, name) == 0)
            return wmem_strdup_printf(wmem_file_scope(), "BU 0x%04x (%s, %s)", origin,
                                      address_to_str(pinfo->pool, &pinfo->src), chan->where);
    }
    return name;
}

/* A BU on one channel has one address. A packet from that address with
 * another origin is the same BU with a new origin (replaced or
 * reconfigured: flagged); one from another address is another BU. */
static eglink_bu_t *
eglink_bu_lookup(packet_info *pinfo, eglink_chan_t *chan, guint16 origin)
{
    eglink_bu_t *bu;

    for (bu = chan->bus; bu; bu = bu->next)
        if (addresses_equal(&bu->addr, &pinfo->src))
            return bu;
    bu = wmem_new0(wmem_file_scope(), eglink_bu_t);
    bu->chan = chan;
    bu->origin = origin;
    bu->name = eglink_bu_name(pinfo, chan, origin);
    copy_address_wmem(wmem_file_scope(), &bu->addr, &pinfo->src);
    if (!eglink_bu_by_index)
        eglink_bu_by_index = wmem_array_new(wmem_file_scope(), sizeof(eglink_bu_t *));
    bu->index = wmem_array_get_count(eglink_bu_by_index);
    wmem_array_append_one(eglink_bu_by_index, bu);
    bu->next = chan->bus;
    chan->bus = bu;
    chan->n_bus++;
    return bu;
}

/* A controller whose packets went to a port of its own, where no BU is,
 * and that now turns up on a BU's channel of the same group, or on a BU
 * input port's (an excerpt
 * that starts with a packet it sent to a wrong port): those packets were
 * this conversation's. It moves here, its serials, intervals and commands
 * going on; the second pass shows its earlier packets joined, on the wrong
 * port (show_orphan()). NULL when there is no such controller. */
static eglink_ctrl_t *
eglink_ctrl_adopt(packet_info *pinfo, eglink_chan_t *chan)
{
    eglink_group_t *group = chan->n_bus || !chan->own_port ? eglink_group(pinfo, FALSE) : NULL;
    eglink_chan_t *own;
    eglink_ctrl_t **link, *ctrl;

    for (own = group ? group->chans : NULL; own; own = own->group_next) {
        if (!own->own_port || own->n_bus)
            continue;
        for (link = &own->ctrls; *link; link = &(*link)->next) {
            ctrl = *link;
            if (!addresses_equal(&ctrl->addr, &pinfo->src))
                continue;
            *link = ctrl->next;
            own->n_ctrls--;
            ctrl->next = chan->ctrls;
            chan->ctrls = ctrl;
            chan->n_ctrls++;
            ctrl->chan = chan;
            ctrl->adopted = TRUE;
            return ctrl;
        }
    }
    return NULL;
}

static eglink_ctrl_t *
eglink_ctrl_lookup(packet_info *pinfo, eglink_chan_t *chan)
{
    eglink_ctrl_t *ctrl;

    for (ctrl = chan->ctrls; ctrl; ctrl = ctrl->next)
        if (addresses_equal(&ctrl->addr, &pinfo->src))
            return ctrl;
    ctrl = eglink_ctrl_adopt(pinfo, chan);
    if (ctrl)
        return ctrl;
    ctrl = wmem_new0(wmem_file_scope(), eglink_ctrl_t);
    ctrl->chan = chan;
    ctrl->name = wmem_strdup_printf(wmem_file_scope(), "Controller %s (BU not known)",
                                    address_to_str(pinfo->pool, &pinfo->src));
    copy_address_wmem(wmem_file_scope(), &ctrl->addr, &pinfo->src);
    if (!eglink_ctrl_by_index)
        eglink_ctrl_by_index = wmem_array_new(wmem_file_scope(), sizeof(eglink_ctrl_t *));
    ctrl->index = wmem_array_get_count(eglink_ctrl_by_index);
    wmem_array_append_one(eglink_ctrl_by_index, ctrl);
    ctrl->next = chan->ctrls;
    chan->ctrls = ctrl;
    chan->n_ctrls++;
    return ctrl;
}

static void
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

/* One BU and one controller on a channel belong together (the usual
 * installation, and every single-BU capture). That holds only while they
 * are alone: a second BU or controller on the channel withdraws such a
 * join (noted on this packet), and from then on a controller is joined to
 * its BU only by the commands acknowledged between them. */
static void
join_if_alone(eglink_chan_t *chan, eglink_frame_t *fd, packet_info *pinfo)
{
    eglink_ctrl_t *ctrl;

    if (chan->n_bus == 1 && chan->n_ctrls == 1) {
        if (!chan->ctrls->bu)
            chan->ctrls->bu = chan->ctrls->alone_bu = chan->bus;
        return;
    }
    for (ctrl = chan->ctrls; ctrl; ctrl = ctrl->next) {
        if (!ctrl->bu || ctrl->joined_by_ack)
            continue;
        ctrl->bu = NULL;
        ctrl->withdrawn_frame = pinfo->num;
        add_finding(fd, FND_JOIN_WITHDRAWN, 0, ctrl->index, chan->n_bus > 1);
    }
}

/* ---------------------------------------------------------------------- */
/* First pass                                                              */

/* A packet of this sender that failed its CRC or size check: not analysed,
 * but its serial, if it holds one, is in the capture. */
static void
remember_corrupted(eglink_sender_t *s, packet_info *pinfo, const eglink_info_t *info)
{
    guint i;

    if (!info->has_serial)
        return;
    i = s->n_bad < EGLINK_BAD_SLOTS ? s->n_bad++ : EGLINK_BAD_SLOTS - 1;
    s->bad_frame[i] = pinfo->num;
    s->bad_serial[i] = info->serial;
    s->bad_crc[i] = !info->crc_ok;
}

/* The serials missing before this packet (count of them from expected) that
 * arrived, with a bad CRC or size: no loss, each named on this packet. */
static void
match_corrupted(const eglink_sender_t *s, eglink_frame_t *fd, guint16 expected, guint16 count)
{
    guint i;

    for (i = 0; i < s->n_bad; i++)
        if ((guint16)(s->bad_serial[i] - expected) < count)
            add_finding(fd, FND_CORRUPTED, s->bad_frame[i],
                        s->bad_serial[i] | (s->bad_crc[i] ? EGLINK_CORRUPTED_CRC : 0), 0);
}

/* Packets lost before this one: the serial gap less the packets in it that
 * arrived corrupted. */
static guint
serial_lost(const eglink_frame_t *fd, guint16 serial)
{
    const eglink_finding_t *f;
    guint lost;

    if (fd->serial_status != SERIAL_LOST)
        return 0;
    lost = (guint16)(serial - fd->expected_serial);
    for (f = fd->findings; f; f = f->next)
        if (f->kind == FND_CORRUPTED && lost)
            lost--;
    return lost;
}

/* The clock stepped back: every time the analysis measures (intervals,
 * periodic packets missing, command deadlines, BU state periods) starts
 * again from now. */
static void
sender_restart_clock(eglink_sender_t *s, const nstime_t *now)
{
    int i;

    if (s->last_periodic_frame) {
        s->last_periodic_ts = *now;
        s->clock_restart = TRUE;
    }
    for (i = 0; i < EGLINK_CMD_SLOTS; i++) {
        eglink_cmd_t *cmd = s->cmds[i];
        if (cmd && !cmd->ack_frame && !cmd->failed) {
            cmd->first_ts = cmd->last_ts = *now;
            cmd->clock_step = TRUE;
            cmd->resend_reported = TRUE;    /* its resends cannot be timed across the step */
        }
    }
}

static void
restart_clock(const nstime_t *now)
{
    guint i;

    for (i = 0; eglink_bu_by_index && i < wmem_array_get_count(eglink_bu_by_index); i++) {
        eglink_bu_t *bu = *(eglink_bu_t **)wmem_array_index(eglink_bu_by_index, i);
        sender_restart_clock(&bu->s, now);
        bu->state_since = *now;
        bu->state_since_step = TRUE;
    }
    for (i = 0; eglink_ctrl_by_index && i < wmem_array_get_count(eglink_ctrl_by_index); i++) {
        eglink_ctrl_t *ctrl = *(eglink_ctrl_t **)wmem_array_index(eglink_ctrl_by_index, i);
        sender_restart_clock(&ctrl->s, now);
        ctrl->burst.have_start_ts = FALSE;
    }
}

/* Time going backwards from one EG-Link packet to the next (a clock set
 * back while capturing, or captures of two clocks merged) is a finding on
 * the packet where it happens, and the rules that measure time restart
 * there. Going back less than EGLINK_CLOCK_JITTER_NS is not: the latest
 * time is kept. */
static void
check_clock(packet_info *pinfo, eglink_frame_t *fd)
{
    gint64 back = eglink_last_ts_frame ? ns_signed(&eglink_last_ts, &pinfo->abs_ts) : 0;

    if (back > EGLINK_CLOCK_JITTER_NS) {
        add_finding(fd, FND_TIME_BACKWARDS, eglink_last_ts_frame, 0, back);
        restart_clock(&pinfo->abs_ts);
    } else if (back > 0) {
        return;
    }
    eglink_last_ts = pinfo->abs_ts;
    eglink_last_ts_frame = pinfo->num;
}

/* TS-0006 §3.2 numbers a sender's packets sequentially and says nothing of
 * where a sender starts: a serial that falls back a little is a repeat,
 * unless the sender shows that it started again. It does when its periodic
 * packets (VRPI of a BU, VRPO of a controller) stopped for longer than
 * their gap limit, as in a power cycle, or when its VRPI reports BU state
 * Initial ("not fully operative yet", TS-0006 §4.1.1). A BU power-cycled
 * soon after it started falls back by less than the repeat window.
 * input: the packet is the BU's (else its controller's). */
static void
track_serial(eglink_sender_t *s, eglink_frame_t *fd, packet_info *pinfo, const eglink_info_t *info,
             gboolean input)
{
    guint16 serial = info->serial;
    guint16 expected, delta;
    gboolean restarted;

    if (!s->have_serial) {
        fd->serial_status = SERIAL_FIRST;
    } else {
        expected = (guint16)(s->last_serial + 1);
        fd->expected_serial = expected;
        delta = (guint16)(serial - s->last_serial);
        if (delta == 1) {
            fd->serial_status = SERIAL_OK;
        } else if (delta == 0) {
            fd->serial_status = SERIAL_REPEAT;
            add_finding(fd, FND_REPEAT, s->last_serial_frame, s->last_serial, 0);
            return;
        } else if (delta < 0x8000) {
            fd->serial_status = SERIAL_LOST;
            match_corrupted(s, fd, expected, (guint16)(delta - 1));
        } else {
            restarted = (info->type == EGLINK_TYPE_VRPI && info->has_bu_state && info->bu_state == 0x00) ||
                (s->last_periodic_frame && !s->clock_restart &&
                 ns_between(&pinfo->abs_ts, &s->last_periodic_ts) >
                     ms_to_ns(input ? pref_vrpi_gap_ms : pref_vrpo_gap_ms));
            if ((guint16)(s->last_serial - serial) <= EGLINK_SERIAL_REPEAT_WINDOW && !restarted) {
                fd->serial_status = SERIAL_REPEAT;
                add_finding(fd, FND_REPEAT, 0, s->last_serial, 0);
                return;
            }
            fd->serial_status = SERIAL_RESTART;
            add_finding(fd, FND_RESTART, 0, s->last_serial, 0);
        }
    }
    s->have_serial = TRUE;
    s->last_serial = serial;
    s->last_serial_frame = pinfo->num;
    s->n_bad = 0;
}

static gint64
ack_timeout_ns(int dir)
{
    return ms_to_ns(dir == EGLINK_DIR_IN ? pref_vrci_ack_timeout_ms : pref_vrco_ack_timeout_ms);
}

static gint64
resend_limit_ns(void)
{
    return ms_to_ns(EGLINK_RESEND_INTERVAL_MS + pref_resend_tolerance_ms);
}

/* TS-0006 5.1.3, 5.1.4: a command is resent every 100 ms until it is
 * acknowledged (or its timeout passes). Flagged once per command, on the
 * first packet of its BU or controller more than 100 ms + the tolerance
 * after its latest transmission while it is unacknowledged, when that
 * resend was due before its deadline. */
static void
check_resend_due(eglink_cmd_t *cmd, eglink_frame_t *fd, packet_info *pinfo, int dir)
{
    gint64 since, interval = ms_to_ns(EGLINK_RESEND_INTERVAL_MS);

    if (cmd->ack_frame || cmd->failed || cmd->resend_reported)
        return;
    since = ns_between(&pinfo->abs_ts, &cmd->last_ts);
    if (since <= resend_limit_ns())
        return;
    if (ns_between(&cmd->last_ts, &cmd->first_ts) + interval >= ack_timeout_ns(dir))
        return;                 /* the next resend would fall past the deadline */
    cmd->resend_reported = TRUE;
    add_finding(fd, FND_NOT_RESENT, cmd->last_frame, cmd->command_id | ((guint32)dir << 16), since);
}

/* Commands of one sender whose deadline (or resend) passed before now.
 * own_id: the Command ID of this packet when it is a VRCI/VRCO of this
 * sender (its resend is timed by track_command()), else -1. */
static void
check_commands(eglink_sender_t *s, eglink_frame_t *fd, packet_info *pinfo, int dir, gint32 own_id)
{
    gint64 timeout = ack_timeout_ns(dir);
    int i;

    for (i = 0; i < EGLINK_CMD_SLOTS; i++) {
        eglink_cmd_t *cmd = s->cmds[i];
        gint64 age;

        if (cmd && (gint32)cmd->command_id != own_id)
            check_resend_due(cmd, fd, pinfo, dir);
        /* The acknowledgement this packet carries, even late, is not a
         * deadline passing unnoticed: track_ack() records it. */
        if (!cmd || cmd->ack_frame || cmd->failed || cmd == fd->cmd)
            continue;
        age = ns_between(&pinfo->abs_ts, &cmd->first_ts);
        if (age > timeout) {
            cmd->failed = TRUE;
            cmd->deadline_frame = pinfo->num;
            add_finding(fd, dir == EGLINK_DIR_IN ? FND_FAILED_VRCI : FND_FAILED_VRCO,
                        cmd->first_frame, cmd->command_id, age);
        }
    }
}

/* Periodic packets of one sender that stopped for longer than the threshold. */
static void
check_periodic(eglink_sender_t *s, eglink_frame_t *fd, packet_info *pinfo, guint threshold_ms,
               eglink_finding_kind_t kind)
{
    gint64 age;

    if (!s->last_periodic_frame || s->periodic_missing_reported)
        return;
    age = ns_between(&pinfo->abs_ts, &s->last_periodic_ts);
    if (age > ms_to_ns(threshold_ms)) {
        s->periodic_missing_reported = TRUE;
        add_finding(fd, kind, s->last_periodic_frame, 0, age);
    }
}

/* Reports what a one-pass reader learns from the time of this packet alone:
 * periodic packets that stopped, commands whose deadline passed. A packet
 * speaks for its BU and the controllers joined to it; a controller whose
 * BU is not known speaks for itself only. */
static void
check_deadlines(eglink_chan_t *chan, eglink_bu_t *bu, eglink_ctrl_t *sender, eglink_frame_t *fd,
                packet_info *pinfo, const eglink_info_t *info)
{
    eglink_type_t type = info->type;
    gint32 vrci_id = type == EGLINK_TYPE_VRCI && info->has_command_id ? info->command_id : -1;
    gint32 vrco_id = type == EGLINK_TYPE_VRCO && info->has_command_id ? info->command_id : -1;
    eglink_ctrl_t *ctrl;

    if (bu && type != EGLINK_TYPE_VRPI)
        check_periodic(&bu->s, fd, pinfo, pref_vrpi_gap_ms, FND_VRPI_MISSING);
    for (ctrl = chan->ctrls; ctrl; ctrl = ctrl->next) {
        if (ctrl != sender && (!bu || ctrl->bu != bu))
            continue;
        if (!(ctrl == sender && type == EGLINK_TYPE_VRPO))
            check_periodic(&ctrl->s, fd, pinfo, pref_vrpo_gap_ms, FND_VRPO_MISSING);
    }
    if (bu)
        check_commands(&bu->s, fd, pinfo, EGLINK_DIR_IN, sender ? -1 : vrci_id);
    for (ctrl = chan->ctrls; ctrl; ctrl = ctrl->next)
        if (ctrl == sender || (bu && ctrl->bu == bu))
            check_commands(&ctrl->s, fd, pinfo, EGLINK_DIR_OUT, ctrl == sender ? vrco_id : -1);
}

/* The most recent command of this sender with this ID. */
static eglink_cmd_t *
find_command(eglink_sender_t *s, guint16 command_id)
{
    eglink_cmd_t *best = NULL;
    int i;

    for (i = 0; i < EGLINK_CMD_SLOTS; i++) {
        eglink_cmd_t *cmd = s->cmds[i];
        if (cmd && cmd->command_id == command_id &&
            (!best || cmd->first_frame > best->first_frame))
            best = cmd;
    }
    return best;
}

/* TS-0006 5.1.3, 5.1.4: a retransmission comes 100 ms after the previous
 * transmission (within the tolerance), and only while the command waits for
 * its acknowledgement: not after it, nor after the deadline. */
static void
check_resend(const eglink_cmd_t *cmd, eglink_frame_t *fd, packet_info *pinfo, int dir)
{
    guint32 value = cmd->command_id | ((guint32)dir << 16);
    gint64 interval = ns_between(&pinfo->abs_ts, &cmd->last_ts);
    gint64 off = interval - ms_to_ns(EGLINK_RESEND_INTERVAL_MS);

    if (cmd->ack_frame) {
        add_finding(fd, FND_RESENT_AFTER_ACK, cmd->ack_frame, value, 0);
        return;
    }
    if (cmd->failed) {
        add_finding(fd, FND_RESENT_AFTER_DEADLINE, cmd->first_frame, value,
                    ns_between(&pinfo->abs_ts, &cmd->first_ts));
        return;
    }
    if (!cmd->clock_step && (off > ms_to_ns(pref_resend_tolerance_ms) || -off > ms_to_ns(pref_resend_tolerance_ms)))
        add_finding(fd, FND_RESEND_INTERVAL, cmd->last_frame, value, interval);
}

/* TS-0006 4.3, 4.5: a sender numbers its commands sequentially: a new
 * command's ID is the previous one + 1 (65535 is followed by 0). The first
 * command of a sender, or the first after it restarted, sets the count. */
static void
check_command_id(eglink_sender_t *s, eglink_frame_t *fd, int dir, guint16 command_id)
{
    guint16 expected = (guint16)(s->last_cmd_id + 1);

    if (s->have_cmd_id && command_id != expected)
        add_finding(fd, FND_CMD_ID_SEQUENCE, 0, expected | ((guint32)dir << 16), s->last_cmd_id);
    s->have_cmd_id = TRUE;
    s->last_cmd_id = command_id;
}

static void
track_command(eglink_sender_t *s, eglink_frame_t *fd, packet_info *pinfo, int dir, guint16 command_id)
{
    eglink_cmd_t *cmd = find_command(s, command_id);

    /* Same Command ID, sent again while the sender may still be waiting for
     * its acknowledgement: a retransmission. Much later it is a new command
     * that reuses the ID (wrap-around, restarted sender). */
    if (cmd && ns_between(&pinfo->abs_ts, &cmd->last_ts) <= ack_timeout_ns(dir)) {
        fd->flags |= FF_RETRANS;
        check_resend(cmd, fd, pinfo, dir);
        cmd->last_ts = pinfo->abs_ts;
        cmd->last_frame = pinfo->num;
    } else {
        check_command_id(s, fd, dir, command_id);
        cmd = wmem_new0(wmem_file_scope(), eglink_cmd_t);
        cmd->first_ts = pinfo->abs_ts;
        cmd->last_ts = pinfo->abs_ts;
        cmd->first_frame = pinfo->num;
        cmd->last_frame = pinfo->num;
        cmd->command_id = command_id;
        cmd->dir = (guint8)dir;
        s->cmds[s->cmd_next] = cmd;
        s->cmd_next = (s->cmd_next + 1) % EGLINK_CMD_SLOTS;
    }
    fd->cmd = cmd;
}

static gboolean
waits_for_ack(const eglink_cmd_t *cmd)
{
    return cmd && !cmd->ack_frame;
}

/* The VRCI a VRAO from this controller acknowledges. Its own BU's first;
 * while that is not known from an acknowledgement, the BU of the channel
 * waiting longest for this Command ID, and the controller joins that BU. */
static eglink_cmd_t *
vrci_acknowledged(eglink_ctrl_t *ctrl, guint16 command_id)
{
    eglink_cmd_t *cmd = ctrl->bu ? find_command(&ctrl->bu->s, command_id) : NULL;
    eglink_cmd_t *best = NULL;
    eglink_bu_t *bu, *best_bu = NULL;

    if (ctrl->joined_by_ack || waits_for_ack(cmd))
        return cmd;
    for (bu = ctrl->chan->bus; bu; bu = bu->next) {
        eglink_cmd_t *c = find_command(&bu->s, command_id);
        if (waits_for_ack(c) && (!best || c->first_frame < best->first_frame)) {
            best = c;
            best_bu = bu;
        }
    }
    if (!best)
        return cmd;
    ctrl->bu = best_bu;
    ctrl->joined_by_ack = TRUE;
    return best;
}

/* The VRCO a VRAI from this BU acknowledges: from a controller joined to it
 * first; else the one of the channel waiting longest for this Command ID,
 * whose BU is not known from an acknowledgement yet: it joins this BU. */
static eglink_cmd_t *
vrco_acknowledged(eglink_bu_t *bu, guint16 command_id)
{
    eglink_ctrl_t *ctrl, *best_ctrl = NULL, *mine_ctrl = NULL;
    eglink_cmd_t *best = NULL, *mine = NULL;

    for (ctrl = bu->chan->ctrls; ctrl; ctrl = ctrl->next) {
        eglink_cmd_t *c;
        if (ctrl->bu != bu)
            continue;
        c = find_command(&ctrl->s, command_id);
        if (c && (!mine || c->first_frame > mine->first_frame)) {
            mine = c;
            mine_ctrl = ctrl;
        }
    }
    if (waits_for_ack(mine)) {
        mine_ctrl->joined_by_ack = TRUE;    /* (evidence now, not only being alone) */
        return mine;
    }
    for (ctrl = bu->chan->ctrls; ctrl; ctrl = ctrl->next) {
        eglink_cmd_t *c;
        if (ctrl->joined_by_ack)
            continue;
        c = find_command(&ctrl->s, command_id);
        if (waits_for_ack(c) && (!best || c->first_frame < best->first_frame)) {
            best = c;
            best_ctrl = ctrl;
        }
    }
    if (!best)
        return mine;
    best_ctrl->bu = bu;
    best_ctrl->joined_by_ack = TRUE;
    return best;
}

static void
track_ack(eglink_cmd_t *cmd, eglink_frame_t *fd, packet_info *pinfo, int dir, guint16 command_id)
{
    gint64 age;

    if (!cmd) {
        add_finding(fd, FND_UNKNOWN_ACK, 0, command_id, 0);
        return;
    }
    fd->cmd = cmd;
    age = ns_between(&pinfo->abs_ts, &cmd->first_ts);
    /* (after a clock step the age counts from the step: no acknowledgement time) */
    if (!cmd->clock_step) {
        fd->delta_ns = age;
        fd->flags |= FF_DELTA;
    }
    if (!cmd->ack_frame) {
        cmd->ack_frame = pinfo->num;
        fd->flags |= FF_FIRST_ACK;
        if (age > ack_timeout_ns(dir)) {
            add_finding(fd, FND_LATE_ACK, cmd->first_frame, command_id, age);
            /* The acknowledgement is the first packet after the deadline:
             * the deadline was seen passing here. */
            if (!cmd->failed) {
                cmd->failed = TRUE;
                cmd->deadline_frame = pinfo->num;
            }
        }
    }
}

/* The acknowledgement of the frame being analysed that waits, in its
 * stored record, for its controller to turn up with a BU. */
static eglink_orphan_ack_t *eglink_orphan_pending;

/* A VRAO a controller on a port of its own sent for a command not seen:
 * kept, with its record, until the controller turns up with a BU. */
static void
remember_orphan_ack(eglink_ctrl_t *ctrl, packet_info *pinfo, guint16 command_id)
{
    eglink_orphan_ack_t *o;

    if (ctrl->n_orphan_acks >= EGLINK_ORPHAN_ACKS)
        return;
    o = &ctrl->orphan_acks[ctrl->n_orphan_acks++];
    o->fd = NULL;
    o->ts = pinfo->abs_ts;
    o->frame = pinfo->num;
    o->command_id = command_id;
    eglink_orphan_pending = o;
}

/* The controller turned up with a BU: the VRAOs it sent before, on a port
 * of its own, acknowledge that BU's VRCIs still waiting (in time); their
 * records say so from the second pass on. */
static void
match_orphan_acks(eglink_ctrl_t *ctrl)
{
    guint i;

    for (i = 0; i < ctrl->n_orphan_acks; i++) {
        eglink_orphan_ack_t *o = &ctrl->orphan_acks[i];
        eglink_cmd_t *cmd = vrci_acknowledged(ctrl, o->command_id);
        eglink_finding_t **f;
        gint64 age;

        if (!o->fd || !waits_for_ack(cmd) || cmd->failed || cmd->first_frame > o->frame)
            continue;
        age = ns_between(&o->ts, &cmd->first_ts);
        if (age > ack_timeout_ns(EGLINK_DIR_IN))
            continue;
        cmd->ack_frame = o->frame;
        ctrl->joined_by_ack = TRUE;
        o->fd->cmd = cmd;
        o->fd->flags |= FF_FIRST_ACK;
        if (!cmd->clock_step) {
            o->fd->delta_ns = age;
            o->fd->flags |= FF_DELTA;
        }
        for (f = &o->fd->findings; *f; f = &(*f)->next) {
            if ((*f)->kind == FND_UNKNOWN_ACK) {
                *f = (*f)->next;
                break;
            }
        }
    }
    ctrl->n_orphan_acks = 0;
}

static gboolean
burst_ends_here(const eglink_burst_t *b, int data_len)
{
    if (data_len < EGLINK_VRPO_FRAGMENT_MAX)
        return TRUE;
    return pref_periodic_size != 0 && b->bytes >= pref_periodic_size;
}

static void
burst_check_size(const eglink_burst_t *b, eglink_frame_t *fd)
{
    if (pref_periodic_size != 0 && b->bytes != pref_periodic_size)
        add_finding(fd, FND_BURST_SIZE, 0, b->bytes, pref_periodic_size);
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
    } else if (!b->broken && pref_periodic_size == 0) {
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
            iv <= ms_to_ns(pref_vrpo_gap_ms))
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

    if (delay > ms_to_ns(pref_burst_spread_ms))
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
static void
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
               ns_between(&pinfo->abs_ts, &b->prev_ts) <= ms_to_ns(pref_burst_spread_ms)) {
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

/* VRPI of a BU or VRPO of a controller: the interval since the previous one. */
static void
track_interval(eglink_sender_t *s, eglink_frame_t *fd, packet_info *pinfo, guint threshold_ms,
               eglink_finding_kind_t gap)
{
    if (s->last_periodic_frame && !s->clock_restart) {
        fd->delta_ns = ns_between(&pinfo->abs_ts, &s->last_periodic_ts);
        fd->flags |= FF_DELTA;
        if (fd->delta_ns > ms_to_ns(threshold_ms))
            add_finding(fd, gap, s->last_periodic_frame, 0, fd->delta_ns);
    }
    s->last_periodic_frame = pinfo->num;
    s->last_periodic_ts = pinfo->abs_ts;
    s->periodic_missing_reported = FALSE;
    s->clock_restart = FALSE;
}

static void
track_vrpi(eglink_bu_t *bu, eglink_frame_t *fd, packet_info *pinfo, const eglink_info_t *info)
{
    track_interval(&bu->s, fd, pinfo, pref_vrpi_gap_ms, FND_VRPI_GAP);
    if (info->has_bu_state) {
        if (bu->have_bu_state) {
            /* The finding carries the length of the period that ends here
             * (for Statistics > EG-Link). */
            if (bu->bu_state != info->bu_state) {
                /* (-1: its length is not known, the clock stepped back) */
                add_finding(fd, FND_BU_STATE, 0, bu->bu_state,
                            bu->state_since_step ? -1 : ns_between(&pinfo->abs_ts, &bu->state_since));
                bu->state_since = pinfo->abs_ts;
                bu->state_since_step = FALSE;
            }
        } else {
            bu->state_since = pinfo->abs_ts;
        }
        bu->have_bu_state = TRUE;
        bu->bu_state = info->bu_state;
    }
}

/* Several BUs or controllers on one group and port: every controller's
 * VRPO and VRCO reach every BU there. Said once per sender. */
static void
check_shared(eglink_chan_t *chan, eglink_sender_t *s, eglink_frame_t *fd)
{
    if (s->shared_reported || (chan->n_bus < 2 && chan->n_ctrls < 2))
        return;
    s->shared_reported = TRUE;
    add_finding(fd, FND_SHARED_GROUP, 0, chan->n_bus, chan->n_ctrls);
}

/* TS-0006 5.1.5: a receiver ignores packets with unsupported header values.
 * A packet of another revision (another layout) is kept out of the
 * analysis; its serial is the sender's, so it is counted. */
static void
track_revision(eglink_sender_t *s, eglink_frame_t *fd, packet_info *pinfo, const eglink_info_t *info)
{
    fd->flags |= FF_REVISION;
    add_finding(fd, FND_REVISION, 0, info->revision, 0);
    track_serial(s, fd, pinfo, info, eglink_is_input(info->type));
}

static void
analyse_packet(packet_info *pinfo, const eglink_info_t *info, eglink_frame_t *fd)
{
    gboolean input = eglink_is_input(info->type);
    guint32 expected_port = 0;
    eglink_chan_t *chan = input ? eglink_bu_chan(pinfo, &expected_port)
                                : eglink_ctrl_chan(pinfo, &expected_port);
    eglink_bu_t *bu = NULL;
    eglink_ctrl_t *ctrl = NULL;
    eglink_sender_t *s;

    check_clock(pinfo, fd);
    if (input) {
        bu = eglink_bu_lookup(pinfo, chan, info->origin);
        s = &bu->s;
    } else {
        ctrl = eglink_ctrl_lookup(pinfo, chan);
        s = &ctrl->s;
    }
    join_if_alone(chan, fd, pinfo);
    if (ctrl && ctrl->n_orphan_acks && chan->n_bus)
        match_orphan_acks(ctrl);
    fd->bu = input ? bu : ctrl->bu;
    fd->ctrl = input || ctrl->joined_by_ack ? NULL : ctrl;
    if (fd->bu) {
        fd->flags |= FF_ORIGIN;
        fd->bu_origin = fd->bu->origin;
    }
    /* Receivers silently drop illegal packets (TS-0006 5.1.5); so does the
     * analysis, but for their serial: a gap it fills is no loss. */
    if (!info->crc_ok || !info->size_ok) {
        fd->flags |= FF_INVALID;
        remember_corrupted(s, pinfo, info);
        return;
    }
    if (expected_port)
        add_finding(fd, FND_WRONG_PORT, 0, expected_port, 0);
    if (info->revision != 0) {
        track_revision(s, fd, pinfo, info);
        return;
    }

    if (input && !bu->origin_known) {
        /* Known so far only from packets that failed their check: no origin
         * change (the BU keeps its name, so that every pass names it alike). */
        bu->origin = info->origin;
        fd->bu_origin = bu->origin;
    } else if (input && bu->origin != info->origin) {
        /* Another device at the BU's address: it counts its own serials. */
        add_finding(fd, FND_ORIGIN, 0, bu->origin, 0);
        bu->origin = info->origin;
        bu->s.have_serial = FALSE;
        fd->bu_origin = bu->origin;
    }
    if (input)
        bu->origin_known = TRUE;

    track_serial(s, fd, pinfo, info, input);
    if (fd->serial_status == SERIAL_REPEAT)
        return;
    if (fd->serial_status == SERIAL_RESTART || fd->serial_status == SERIAL_FIRST)
        s->have_cmd_id = FALSE;     /* a sender (re)starting numbers its commands afresh */

    /* An acknowledgement may tell which BU a controller talks to. */
    if (info->type == EGLINK_TYPE_VRAO && info->has_command_id) {
        fd->cmd = vrci_acknowledged(ctrl, info->command_id);
        if (waits_for_ack(fd->cmd))
            ctrl->joined_by_ack = TRUE;     /* (evidence now, not only being alone) */
    } else if (info->type == EGLINK_TYPE_VRAI && info->has_command_id) {
        fd->cmd = vrco_acknowledged(bu, info->command_id);
    }
    if (ctrl && ctrl->joined_by_ack && (fd->ctrl || ctrl->bu != fd->bu)) {
        fd->bu = ctrl->bu;
        fd->ctrl = NULL;
        fd->flags |= FF_ORIGIN;
        fd->bu_origin = fd->bu->origin;
    }

    check_shared(chan, s, fd);
    check_deadlines(chan, fd->bu, ctrl, fd, pinfo, info);

    switch (info->type) {
    case EGLINK_TYPE_VRPI:
        track_vrpi(bu, fd, pinfo, info);
        break;
    case EGLINK_TYPE_VRPO:
        track_interval(s, fd, pinfo, pref_vrpo_gap_ms, FND_VRPO_GAP);
        if (info->has_packet_number)
            track_burst(&ctrl->burst, fd, pinfo, info);
        break;
    case EGLINK_TYPE_VRCI:
    case EGLINK_TYPE_VRCO:
        if (info->has_command_id)
            track_command(s, fd, pinfo, input ? EGLINK_DIR_IN : EGLINK_DIR_OUT, info->command_id);
        break;
    case EGLINK_TYPE_VRAO:      /* acknowledges a VRCI */
    case EGLINK_TYPE_VRAI:      /* acknowledges a VRCO */
        if (info->has_command_id) {
            eglink_cmd_t *cmd = fd->cmd;
            fd->cmd = NULL;
            track_ack(cmd, fd, pinfo, input ? EGLINK_DIR_OUT : EGLINK_DIR_IN, info->command_id);
            if (!cmd && !input && chan->own_port && !chan->n_bus)
                remember_orphan_ack(ctrl, pinfo, info->command_id);
        }
        break;
    default:
        break;
    }
}

/* ---------------------------------------------------------------------- */
/* Every pass: the tree, the expert info, the reassembly and the tap        */

static proto_item *
add_generated_uint(proto_tree *tree, int hf, tvbuff_t *tvb, guint32 value)
{
    proto_item *ti = proto_tree_add_uint(tree, hf, tvb, 0, 0, value);

    proto_item_set_generated(ti);
    return ti;
}

static proto_item *
add_generated_time(proto_tree *tree, int hf, tvbuff_t *tvb, gint64 ns)
{
    nstime_t t = ns_to_nstime(ns);
    proto_item *ti = proto_tree_add_time(tree, hf, tvb, 0, 0, &t);

    proto_item_set_generated(ti);
    return ti;
}

static void
show_serial(proto_tree *at, tvbuff_t *tvb, packet_info *pinfo, const eglink_info_t *info,
            const eglink_frame_t *fd)
{
    proto_item *ti;
    guint lost;

    if (fd->serial_status == SERIAL_FIRST)
        return;
    ti = add_generated_uint(at, hf_expected_serial, tvb, fd->expected_serial);
    lost = serial_lost(fd, info->serial);
    if (lost) {
        ti = add_generated_uint(at, hf_lost, tvb, lost);
        expert_add_info_format(pinfo, ti, &ei_serial_gap,
            "%u packet%s lost from this sender: serial %u expected, %u received",
            lost, lost == 1 ? "" : "s", fd->expected_serial, info->serial);
        col_append_fstr(pinfo->cinfo, COL_INFO, " [lost %u]", lost);
    }
}

static const eglink_finding_t *
find_finding(const eglink_frame_t *fd, eglink_finding_kind_t kind)
{
    const eglink_finding_t *f;

    for (f = fd->findings; f; f = f->next)
        if (f->kind == kind)
            return f;
    return NULL;
}

/* The packet at which the deadline of a command (first sent in `frame`)
 * was seen passing unacknowledged. On the second pass and in the GUI the
 * warning is on the command's frame (show_command()) and this packet gets a
 * note naming the command. In one pass (tshark without -2, as CI runs it)
 * the command's frame is behind the reader already: this packet carries the
 * command's warning itself, so a severity filter or "-z expert" finds every
 * failed command. The [unacked] tag and the link are here on every pass: a
 * live capture colours and draws a row once, from the dissection after its
 * first pass, before any later packet can mark its command; this packet is
 * where a live packet list can show the failure, and the profile colours it
 * by the link. */
static void
show_failed(proto_tree *at, tvbuff_t *tvb, packet_info *pinfo, int dir, guint32 frame, guint32 command_id)
{
    proto_item *ti = add_generated_uint(at, hf_failed_command, tvb, frame);
    gboolean vrci = dir == EGLINK_DIR_IN;
    const char *what = vrci ? "VRCI" : "VRCO";
    const char *ack = vrci ? "VRAO" : "VRAI";
    guint timeout_ms = vrci ? pref_vrci_ack_timeout_ms : pref_vrco_ack_timeout_ms;

    col_append_str(pinfo->cinfo, COL_INFO, " [unacked]");
    if (PINFO_FD_VISITED(pinfo)) {
        expert_add_info_format(pinfo, ti, vrci ? &ei_vrci_deadline : &ei_vrco_deadline,
            "Deadline of %s command %u (frame %u) passed with no %s (%u ms)",
            what, command_id, frame, ack, timeout_ms);
        return;
    }
    expert_add_info_format(pinfo, ti, vrci ? &ei_vrci_unacked : &ei_vrco_unacked,
        "%s command %u (frame %u) not acknowledged by a %s within %u ms%s", what, command_id, frame, ack,
        timeout_ms, vrci ? ": the BU reports to the RU application that the command failed" : "");
}

static void
show_command(proto_tree *at, proto_item *aitem, tvbuff_t *tvb, packet_info *pinfo,
             const eglink_info_t *info, const eglink_frame_t *fd)
{
    const eglink_cmd_t *cmd = fd->cmd;
    const eglink_finding_t *late;
    proto_item *ti;
    const char *what = cmd->dir == EGLINK_DIR_IN ? "VRCI" : "VRCO";
    const char *ack = cmd->dir == EGLINK_DIR_IN ? "VRAO" : "VRAI";
    guint timeout_ms = cmd->dir == EGLINK_DIR_IN ? pref_vrci_ack_timeout_ms : pref_vrco_ack_timeout_ms;

    if (info->type == EGLINK_TYPE_VRCI || info->type == EGLINK_TYPE_VRCO) {
        if (fd->flags & FF_RETRANS) {
            ti = add_generated_uint(at, hf_retransmission_of, tvb, cmd->first_frame);
            expert_add_info_format(pinfo, ti, &ei_retransmission,
                "Retransmission of %s command %u", what, cmd->command_id);
            col_append_str(pinfo->cinfo, COL_INFO, " [Retransmission]");
        } else {
            expert_add_info_format(pinfo, aitem, &ei_command, "New %s command %u", what, cmd->command_id);
        }
        /* Known on the first pass only when the acknowledgement came first:
         * forward links, shown on the second pass and in the GUI. */
        if (cmd->ack_frame) {
            ti = add_generated_uint(at, hf_ack_in, tvb, cmd->ack_frame);
            proto_item_append_text(ti, " (%s)", ack);
        }
        /* The finding sits on the command itself (its first transmission),
         * linked to the packet at which the deadline was seen passing. */
        if (cmd->failed && cmd->deadline_frame && !(fd->flags & FF_RETRANS)) {
            ti = add_generated_uint(at, hf_deadline_in, tvb, cmd->deadline_frame);
            if (cmd->dir == EGLINK_DIR_IN)
                expert_add_info_format(pinfo, ti, &ei_vrci_unacked,
                    "VRCI command %u not acknowledged by a VRAO within %u ms (deadline at frame %u): "
                    "the BU reports to the RU application that the command failed",
                    cmd->command_id, pref_vrci_ack_timeout_ms, cmd->deadline_frame);
            else
                expert_add_info_format(pinfo, ti, &ei_vrco_unacked,
                    "VRCO command %u not acknowledged by a VRAI within %u ms (deadline at frame %u)",
                    cmd->command_id, pref_vrco_ack_timeout_ms, cmd->deadline_frame);
            col_append_str(pinfo->cinfo, COL_INFO, " [unacked]");
        }
    } else {
        ti = add_generated_uint(at, hf_ack_to, tvb, cmd->first_frame);
        proto_item_append_text(ti, " (%s command %u)", what, cmd->command_id);
        if (fd->flags & FF_DELTA)
            add_generated_time(at, hf_ack_time, tvb, fd->delta_ns);
        late = find_finding(fd, FND_LATE_ACK);
        /* A late acknowledgement that is itself the first packet past the
         * deadline: the command failed here, as at any other such packet. */
        if (late && cmd->deadline_frame == pinfo->num && !PINFO_FD_VISITED(pinfo))
            show_failed(at, tvb, pinfo, cmd->dir, cmd->first_frame, cmd->command_id);
        if (late) {
            expert_add_info_format(pinfo, ti, &ei_late_ack,
                "Acknowledges %s command %u %s after its first transmission, later than %u ms",
                what, cmd->command_id, ns_str_past(pinfo->pool, late->ns, timeout_ms), timeout_ms);
            col_append_str(pinfo->cinfo, COL_INFO, " [late ack]");
        } else if ((fd->flags & FF_FIRST_ACK) && (fd->flags & FF_DELTA)) {
            expert_add_info_format(pinfo, ti, &ei_ack, "Acknowledges %s command %u after %s",
                                   what, cmd->command_id, ns_str(pinfo->pool, fd->delta_ns));
        }
    }
}

/* The BU a packet belongs to, for filters and the profile's Device column:
 * its origin, also on a controller's packets from before an acknowledgement
 * joined it to its BU (known on the second pass and in the GUI only). */
static void
show_device(proto_tree *at, proto_item *aitem, tvbuff_t *tvb, packet_info *pinfo, const eglink_frame_t *fd)
{
    const char *device;
    proto_item *ti;

    if (!at)                    /* no tree: nothing to show, no text to format */
        return;
    if (fd->flags & FF_ORIGIN) {
        add_generated_uint(at, hf_bu_origin, tvb, fd->bu_origin);
        device = wmem_strdup_printf(pinfo->pool, "0x%04x", fd->bu_origin);
    } else if (!fd->bu && fd->ctrl && fd->ctrl->bu && fd->ctrl->bu->origin_known) {
        ti = add_generated_uint(at, hf_bu_origin, tvb, fd->ctrl->bu->origin);
        proto_item_append_text(ti, " (joined to this BU by a later acknowledgement)");
        proto_item_append_text(aitem, ", joined to BU 0x%04x later", fd->ctrl->bu->origin);
        device = wmem_strdup_printf(pinfo->pool, "0x%04x", fd->ctrl->bu->origin);
    } else {
        device = fd->bu ? fd->bu->name : "BU not known";
    }
    ti = proto_tree_add_string(at, hf_device, tvb, 0, 0, device);
    proto_item_set_generated(ti);
}

static const char *
plural(guint n, const char *one, const char *many)
{
    return n == 1 ? one : many;
}

static const char *const type_names[] = { "VRPI", "VRPO", "VRCI", "VRCO", "VRAI", "VRAO" };

/* Also on a packet that is not analysed (bad CRC or size): the clock is its own. */
static void
show_time_backwards(proto_tree *at, tvbuff_t *tvb, packet_info *pinfo, const eglink_finding_t *f)
{
    proto_item *ti = add_generated_uint(at, hf_time_backwards_after, tvb, f->frame);
    const char *t = ns_str(pinfo->pool, f->ns);

    expert_add_info_format(pinfo, ti, &ei_time_backwards,
        "Time went backwards by %s (clock step): this packet is older than the EG-Link packet "
        "before it; gap, age and deadline rules restart here", t);
    col_append_fstr(pinfo->cinfo, COL_INFO, " [time backwards %s]", t);
}

static void
show_wrong_port(proto_tree *at, tvbuff_t *tvb, packet_info *pinfo, const eglink_info_t *info, guint32 expected)
{
    proto_item *ti = add_generated_uint(at, hf_expected_port, tvb, expected);

    if (eglink_is_input(info->type))
        expert_add_info_format(pinfo, ti, &ei_wrong_port,
            "%s sent to UDP port %u, the output packet port: the BU sends VRPI, VRCI and VRAI to its "
            "input packet port (%u here, TS-0006 §2.2); analysed with this BU's packets",
            type_names[info->type], pinfo->destport, expected);
    else
        expert_add_info_format(pinfo, ti, &ei_wrong_port,
            "%s sent to UDP port %u%s: the machine controller sends VRPO, VRCO and VRAO to the "
            "BU's input port + 2 (%u here, TS-0006 §2.2); analysed with this controller's packets",
            type_names[info->type], pinfo->destport,
            pinfo->destport + 2 == expected ? ", the BU's input port" : "", expected);
    col_append_str(pinfo->cinfo, COL_INFO, " [wrong port]");
}

/* A controller packet analysed on a port of its own, where no BU is. One
 * pass cannot tell yet whether the controller turns up with a BU later
 * (an excerpt that starts with a packet it sent to a wrong port): said.
 * Once it has (eglink_ctrl_adopt(), the second pass and the GUI), the
 * packet is that BU's, on the wrong port. */
static void
show_orphan(proto_tree *at, proto_item *aitem, tvbuff_t *tvb, packet_info *pinfo, const eglink_info_t *info,
            const eglink_frame_t *fd)
{
    const eglink_ctrl_t *ctrl = fd->ctrl;

    if (!ctrl || fd->bu)
        return;
    if (ctrl->chan->own_port && !ctrl->chan->n_bus) {
        if (!PINFO_FD_VISITED(pinfo))
            expert_add_info_format(pinfo, aitem, &ei_not_joined,
                "%s sent to UDP port %u, where no BU has been seen: not joined to a BU yet (two passes "
                "join it to the BU its controller turns up with later)", type_names[info->type], pinfo->destport);
        return;
    }
    if (ctrl->adopted && pinfo->destport != ctrl->chan->port + 2 && !find_finding(fd, FND_WRONG_PORT))
        show_wrong_port(at, tvb, pinfo, info, ctrl->chan->port + 2);
}

/* The controller joined to its BU only for being alone with it on the
 * channel, which this packet, from a second BU or controller there, withdrew.
 * Also on a packet that is not analysed: the sender is on the channel. */
static void
show_withdrawn(packet_info *pinfo, proto_item *aitem, const eglink_finding_t *f)
{
    const eglink_ctrl_t *ctrl = *(eglink_ctrl_t **)wmem_array_index(eglink_ctrl_by_index, f->value);

    expert_add_info_format(pinfo, aitem, &ei_join_withdrawn,
        "Controller %s no longer joined to %s: only being alone with it on %s joined them, and "
        "this packet is a second %s's there: BU not known until a command acknowledged between "
        "them",
        address_to_str(pinfo->pool, &ctrl->addr), ctrl->alone_bu->name, ctrl->chan->where,
        f->ns ? "BU" : "controller");
}

static const char *const vrpo_break_names[] = { "a gap with no packet lost", "a repeat", "a step back" };

/* The VRPO rules of TS-0006 4.2 and 5.1.2. */
static void
show_vrpo_rule(proto_item *aitem, packet_info *pinfo, const eglink_info_t *info, const eglink_finding_t *f)
{
    switch ((eglink_finding_kind_t)f->kind) {
    case FND_VRPO_NUMBER:
        expert_add_info_format(pinfo, aitem, &ei_vrpo_number,
            "VRPO packet number %u, %u expected (%s): TS-0006 §4.2 increments it by one for each packet",
            info->packet_number, f->value, vrpo_break_names[f->ns < 3 ? f->ns : 0]);
        break;
    case FND_VRPO_INTERVAL:
        expert_add_info_format(pinfo, aitem, &ei_vrpo_interval,
            "VRPO %s after the previous one: TS-0006 §5.1.2 recommends a VRPO every %u to %u ms",
            ns_str_past(pinfo->pool, f->ns, f->ns < ms_to_ns(EGLINK_VRPO_INTERVAL_MIN_MS)
                                            ? EGLINK_VRPO_INTERVAL_MIN_MS : EGLINK_VRPO_INTERVAL_MAX_MS),
            EGLINK_VRPO_INTERVAL_MIN_MS, EGLINK_VRPO_INTERVAL_MAX_MS);
        break;
    case FND_BURST_SPREAD:
        expert_add_info_format(pinfo, aitem, &ei_burst_spread,
            "VRPO packet %u %s after the packet before it in its burst (more than %u ms): TS-0006 "
            "§5.1.2 sends the packets of a split VRPO without delay", info->packet_number,
            ns_str_past(pinfo->pool, f->ns, pref_burst_spread_ms), pref_burst_spread_ms);
        break;
    case FND_VRPO_NOT_FULL:
        expert_add_info_format(pinfo, aitem, &ei_vrpo_not_full,
            "VRPO packet %u (frame %u) carried %u bytes but its burst goes on with packet %u: "
            "TS-0006 §4.2: all packets of a burst but the last are full (%u bytes)",
            f->value & 0xFFFF, f->frame, f->value >> 16, info->packet_number, EGLINK_VRPO_FRAGMENT_MAX);
        break;
    default:
        break;
    }
}

/* The edge of the resend window (100 ms +- the tolerance) a resend
 * interval falls outside of. */
static guint
resend_edge_ms(gint64 ns)
{
    if (ns > ms_to_ns(EGLINK_RESEND_INTERVAL_MS))
        return EGLINK_RESEND_INTERVAL_MS + pref_resend_tolerance_ms;
    return pref_resend_tolerance_ms < EGLINK_RESEND_INTERVAL_MS
           ? EGLINK_RESEND_INTERVAL_MS - pref_resend_tolerance_ms : 0;
}

/* The command rules of TS-0006 4.3, 4.5, 5.1.3 and 5.1.4. */
static void
show_command_rule(proto_item *aitem, packet_info *pinfo, const eglink_info_t *info, const eglink_finding_t *f)
{
    gboolean vrci = (f->value >> 16) == EGLINK_DIR_IN;
    const char *what = vrci ? "VRCI" : "VRCO";
    const char *ack = vrci ? "VRAO" : "VRAI";
    const char *flow = vrci ? "5.1.3" : "5.1.4";
    guint id = f->value & 0xFFFF;
    guint timeout_ms = vrci ? pref_vrci_ack_timeout_ms : pref_vrco_ack_timeout_ms;

    switch ((eglink_finding_kind_t)f->kind) {
    case FND_RESEND_INTERVAL:
        expert_add_info_format(pinfo, aitem, &ei_resend_interval,
            "%s command %u resent %s after its previous transmission (frame %u): TS-0006 §%s "
            "resends it every %u ms (tolerance %u ms)", what, id, ns_str_past(pinfo->pool, f->ns, resend_edge_ms(f->ns)), f->frame,
            flow, EGLINK_RESEND_INTERVAL_MS, pref_resend_tolerance_ms);
        break;
    case FND_NOT_RESENT:
        expert_add_info_format(pinfo, aitem, &ei_not_resent,
            "%s command %u (frame %u) not resent for %s while unacknowledged: TS-0006 §%s "
            "resends it every %u ms until a %s", what, id, f->frame,
            ns_str_past(pinfo->pool, f->ns, EGLINK_RESEND_INTERVAL_MS + pref_resend_tolerance_ms), flow,
            EGLINK_RESEND_INTERVAL_MS, ack);
        break;
    case FND_RESENT_AFTER_ACK:
        expert_add_info_format(pinfo, aitem, &ei_resent_after_ack,
            "%s command %u resent after its %s (frame %u): TS-0006 §%s resends it only until "
            "acknowledged", what, id, ack, f->frame, flow);
        break;
    case FND_RESENT_AFTER_DEADLINE:
        expert_add_info_format(pinfo, aitem, &ei_resent_after_deadline,
            "%s command %u resent %s after its first transmission (frame %u), past its %u ms "
            "deadline: %s", what, id,
            ns_str_past(pinfo->pool, f->ns, timeout_ms), f->frame, timeout_ms,
            /* only 5.1.4 (VRCO) has the sender stop; 5.1.3 has the VRCI failed */
            vrci ? "TS-0006 §5.1.3 has the command failed by then"
                 : "TS-0006 §5.1.4 stops sending the command at the timeout");
        break;
    case FND_CMD_ID_SEQUENCE:
        expert_add_info_format(pinfo, aitem, &ei_command_id_sequence,
            "%s command ID %u after %u, %u expected: TS-0006 §%s numbers commands sequentially",
            what, info->command_id, (guint)f->ns, id, vrci ? "4.3" : "4.5");
        break;
    default:
        break;
    }
}

static void
show_findings(proto_tree *at, proto_item *aitem, tvbuff_t *tvb, packet_info *pinfo,
              const eglink_info_t *info, const eglink_frame_t *fd)
{
    const eglink_finding_t *f;
    proto_item *ti;
    const char *t;

    for (f = fd->findings; f; f = f->next) {
        /* (the gaps below: a VRPI's or a VRPO's, past its threshold) */
        t = ns_str_past(pinfo->pool, f->ns, f->kind == FND_VRPI_GAP || f->kind == FND_VRPI_MISSING
                                            ? pref_vrpi_gap_ms : pref_vrpo_gap_ms);
        switch ((eglink_finding_kind_t)f->kind) {
        case FND_REPEAT:
            ti = aitem;
            if (f->frame)
                ti = add_generated_uint(at, hf_repeat_of, tvb, f->frame);
            if (f->value == info->serial)
                expert_add_info_format(pinfo, ti, &ei_serial_repeat,
                    "Repeated packet: serial %u was already received; not analysed further",
                    info->serial);
            else
                expert_add_info_format(pinfo, ti, &ei_serial_repeat,
                    "Repeated or reordered packet: serial %u is older than the last one received (%u); "
                    "not analysed further", info->serial, f->value);
            col_append_str(pinfo->cinfo, COL_INFO, " [Repeated]");
            break;
        case FND_RESTART:
            expert_add_info_format(pinfo, aitem, &ei_serial_restart,
                "Serial jumped back from %u to %u: the sender restarted?", f->value, info->serial);
            break;
        case FND_ORIGIN:
            expert_add_info_format(pinfo, aitem, &ei_origin_changed,
                "Origin changed from 0x%04x to 0x%04x at the same address: the BU was replaced "
                "or reconfigured", f->value, info->origin);
            break;
        case FND_BU_STATE:
            expert_add_info_format(pinfo, aitem, &ei_bu_state_changed,
                "BU state changed from %s (0x%02x) to %s (0x%02x)",
                eglink_bu_state_name((guint8)f->value), f->value,
                eglink_bu_state_name(info->bu_state), info->bu_state);
            break;
        case FND_VRPI_GAP:
            ti = add_generated_uint(at, hf_last_vrpi, tvb, f->frame);
            expert_add_info_format(pinfo, ti, &ei_vrpi_gap,
                "No VRPI for %s (more than %u ms): the machine controller should have flagged "
                "an error", t, pref_vrpi_gap_ms);
            col_append_fstr(pinfo->cinfo, COL_INFO, " [gap %s]", t);
            break;
        case FND_VRPO_GAP:
            ti = add_generated_uint(at, hf_last_vrpo, tvb, f->frame);
            expert_add_info_format(pinfo, ti, &ei_vrpo_gap,
                "No VRPO for %s (more than %u ms): the BU flags an error and, with an RU armed, "
                "opens the ES-Link relays", t, pref_vrpo_gap_ms);
            col_append_fstr(pinfo->cinfo, COL_INFO, " [gap %s]", t);
            break;
        case FND_VRPI_MISSING:
            ti = add_generated_uint(at, hf_last_vrpi, tvb, f->frame);
            expert_add_info_format(pinfo, ti, &ei_vrpi_missing,
                "No VRPI from this BU for %s (more than %u ms)", t, pref_vrpi_gap_ms);
            col_append_fstr(pinfo->cinfo, COL_INFO, " [no VRPI %s]", t);
            break;
        case FND_VRPO_MISSING:
            ti = add_generated_uint(at, hf_last_vrpo, tvb, f->frame);
            expert_add_info_format(pinfo, ti, &ei_vrpo_missing,
                "No VRPO to this BU for %s (more than %u ms): the BU flags an error and, with "
                "an RU armed, opens the ES-Link relays", t, pref_vrpo_gap_ms);
            col_append_fstr(pinfo->cinfo, COL_INFO, " [no VRPO %s]", t);
            break;
        case FND_FAILED_VRCI:
            show_failed(at, tvb, pinfo, EGLINK_DIR_IN, f->frame, f->value);
            break;
        case FND_FAILED_VRCO:
            show_failed(at, tvb, pinfo, EGLINK_DIR_OUT, f->frame, f->value);
            break;
        case FND_UNKNOWN_ACK:
            expert_add_info_format(pinfo, aitem, &ei_unknown_ack,
                "Acknowledges %s command %u, which is not in the capture",
                info->type == EGLINK_TYPE_VRAO ? "VRCI" : "VRCO", f->value);
            break;
        case FND_BURST_INCOMPLETE:
            ti = add_generated_uint(at, hf_incomplete_burst, tvb, f->frame);
            expert_add_info_format(pinfo, ti, &ei_burst_incomplete,
                "VRPO burst is incomplete (packet %u %s): its periodic data cannot be "
                "reassembled", f->value & 0xFFFF,
                (f->value & EGLINK_BURST_CUT) ? "cut by the capture" : "missing");
            break;
        case FND_BURST_SIZE:
            expert_add_info_format(pinfo, aitem, &ei_burst_size,
                "VRPO burst carries %u bytes of periodic data; the periodic data size "
                "preference says %u", f->value, (guint)f->ns);
            break;
        case FND_SHARED_GROUP:
            expert_add_info_format(pinfo, aitem, &ei_shared_group,
                "%s is shared by several BUs or controllers (so far %u %s%s): each "
                "controller's VRPO and VRCO reach every BU on it; give each BU a group or port "
                "of its own", fd->bu ? fd->bu->chan->where : fd->ctrl->chan->where,
                f->value, plural(f->value, "BU", "BUs"),
                f->ns == 0 ? "" : wmem_strdup_printf(pinfo->pool, " and %u %s", (guint)f->ns,
                                                     plural((guint)f->ns, "controller", "controllers")));
            col_append_str(pinfo->cinfo, COL_INFO, " [shared group]");
            break;
        case FND_CORRUPTED:
            ti = add_generated_uint(at, hf_corrupted_in, tvb, f->frame);
            expert_add_info_format(pinfo, ti, &ei_serial_corrupted,
                "Serial %u arrived with a %s, frame %u: not counted as lost",
                f->value & 0xFFFF, (f->value & EGLINK_CORRUPTED_CRC) ? "bad CRC" : "wrong size", f->frame);
            break;
        case FND_WRONG_PORT:
            show_wrong_port(at, tvb, pinfo, info, f->value);
            break;
        case FND_TIME_BACKWARDS:
            show_time_backwards(at, tvb, pinfo, f);
            break;
        case FND_JOIN_WITHDRAWN:
            show_withdrawn(pinfo, aitem, f);
            break;
        case FND_VRPO_NUMBER:
        case FND_VRPO_INTERVAL:
        case FND_BURST_SPREAD:
        case FND_VRPO_NOT_FULL:
            show_vrpo_rule(aitem, pinfo, info, f);
            break;
        case FND_RESEND_INTERVAL:
        case FND_NOT_RESENT:
        case FND_RESENT_AFTER_ACK:
        case FND_RESENT_AFTER_DEADLINE:
        case FND_CMD_ID_SEQUENCE:
            show_command_rule(aitem, pinfo, info, f);
            break;
        case FND_REVISION:
            expert_add_info_format(pinfo, aitem, &ei_revision_ignored,
                "Revision %u: kept out of the analysis, as TS-0006 §5.1.5 has receivers ignore "
                "unsupported header values (its serial is counted)", f->value);
            break;
        case FND_LATE_ACK:      /* shown with the command link */
        case FND_BURST_DONE:    /* shown with the reassembly */
            break;
        }
    }
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

static void
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
    if (!pref_reassemble)
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

/* A controller packet joined to its BU only for the two being alone on the
 * channel, when a second BU or controller there withdrew that later: the
 * second pass and the GUI show it as the controller's, its BU not known
 * (or the BU an acknowledgement joined it to later), as its packets after. */
static const eglink_frame_t *
frame_view(const eglink_frame_t *fd, eglink_frame_t *buf)
{
    if (!fd->bu || !fd->ctrl || !fd->ctrl->withdrawn_frame)
        return fd;
    *buf = *fd;
    buf->bu = NULL;
    buf->flags &= ~FF_ORIGIN;
    buf->bu_origin = 0;
    return buf;
}

static void
queue_tap(packet_info *pinfo, const eglink_info_t *info, const eglink_frame_t *fd)
{
    eglink_tap_info_t *t = wmem_new0(pinfo->pool, eglink_tap_info_t);
    const eglink_finding_t *f;

    t->bu_name = fd->bu ? fd->bu->name : fd->ctrl->name;
    t->is_bu = fd->bu != NULL;
    t->type = info->type;
    t->invalid = (fd->flags & FF_INVALID) != 0;
    t->repeated = fd->serial_status == SERIAL_REPEAT;
    t->lost = serial_lost(fd, info->serial);
    if ((fd->flags & FF_DELTA) && (info->type == EGLINK_TYPE_VRPI || info->type == EGLINK_TYPE_VRPO)) {
        t->has_interval = TRUE;
        t->interval_ns = fd->delta_ns;
    }
    if (fd->cmd && (info->type == EGLINK_TYPE_VRCI || info->type == EGLINK_TYPE_VRCO)) {
        t->retransmission = (fd->flags & FF_RETRANS) != 0;
        t->new_command = !t->retransmission;
    }
    if (fd->flags & FF_FIRST_ACK) {
        t->first_ack = TRUE;
        t->ack_ns = fd->delta_ns;
    }
    if (fd->flags & FF_BURST_LAST)
        t->burst_complete = TRUE;
    for (f = fd->findings; f; f = f->next) {
        if (f->kind == FND_FAILED_VRCI)
            t->failed[EGLINK_DIR_IN]++;
        else if (f->kind == FND_FAILED_VRCO)
            t->failed[EGLINK_DIR_OUT]++;
        /* A late acknowledgement that is itself the first packet past the
         * deadline: the command failed here too. */
        else if (f->kind == FND_LATE_ACK && fd->cmd && fd->cmd->deadline_frame == pinfo->num)
            t->failed[fd->cmd->dir]++;
        else if (f->kind == FND_BURST_DONE)
            t->burst_complete = TRUE;
        else if (f->kind == FND_BU_STATE && f->ns >= 0) {
            t->has_state_period = TRUE;
            t->prev_state = (guint8)f->value;
            t->state_ns = f->ns;
        }
        else if (f->kind == FND_BURST_INCOMPLETE)
            t->burst_incomplete = TRUE;
    }
    tap_queue_packet(eglink_tap, pinfo, t);
}

void
eglink_analysis_dissect(tvbuff_t *tvb, packet_info *pinfo, proto_tree *eglink_tree,
                        proto_item *eglink_item _U_, const eglink_info_t *info)
{
    guint32 key = EGLINK_ANALYSIS_KEY_BASE + pinfo->curr_layer_num;
    const eglink_frame_t *fd;
    eglink_frame_t buf, view, *stored;
    proto_item *aitem;
    proto_tree *at;

    /* Unknown types are not part of the packet flow; a copy quoted in an
     * ICMP error is not a packet of the conversation. */
    if (info->type == EGLINK_TYPE_UNKNOWN || pinfo->flags.in_error_pkt)
        return;

    if (!PINFO_FD_VISITED(pinfo)) {
        if (pinfo->num == eglink_fp_num && pinfo->fd->file_off != eglink_fp_off) {
            eglink_slot_t *slot = eglink_slot(pinfo->num, FALSE);

            if (slot)
                memset(slot, 0, sizeof(*slot));
        }
        eglink_fp_num = pinfo->num;
        eglink_fp_off = pinfo->fd->file_off;
    }
    fd = eglink_frame_fetch(pinfo, key, info->serial, &buf);
    if (!fd) {
        if (PINFO_FD_VISITED(pinfo))
            return;
        memset(&buf, 0, sizeof(buf));
        eglink_orphan_pending = NULL;
        analyse_packet(pinfo, info, &buf);
        stored = eglink_frame_store(pinfo, key, info->serial, &buf);
        if (eglink_orphan_pending)
            eglink_orphan_pending->fd = stored;
        fd = &buf;
    }
    fd = frame_view(fd, &view);

    aitem = proto_tree_add_item(eglink_tree, hf_analysis, tvb, 0, 0, ENC_NA);
    proto_item_set_generated(aitem);
    at = proto_item_add_subtree(aitem, ett_analysis);
    proto_item_append_text(aitem, ": %s", fd->bu ? fd->bu->name : fd->ctrl->name);
    if (fd->bu)
        add_generated_uint(at, hf_bu_stream, tvb, fd->bu->index);
    if (fd->bu && fd->ctrl)
        proto_item_set_generated(proto_tree_add_boolean(at, hf_joined_alone, tvb, 0, 0, TRUE));
    show_device(at, aitem, tvb, pinfo, fd);

    if (fd->flags & FF_INVALID) {
        const eglink_finding_t *f = find_finding(fd, FND_TIME_BACKWARDS);

        proto_item_append_text(aitem, " (not analysed: CRC or size check failed)");
        if (f)
            show_time_backwards(at, tvb, pinfo, f);
        f = find_finding(fd, FND_JOIN_WITHDRAWN);
        if (f)
            show_withdrawn(pinfo, aitem, f);
    } else {
        show_serial(at, tvb, pinfo, info, fd);
        if ((fd->flags & FF_DELTA) && info->type == EGLINK_TYPE_VRPI)
            add_generated_time(at, hf_time_since_prev_vrpi, tvb, fd->delta_ns);
        if ((fd->flags & FF_DELTA) && info->type == EGLINK_TYPE_VRPO)
            add_generated_time(at, hf_time_since_prev_vrpo, tvb, fd->delta_ns);
        if (fd->cmd)
            show_command(at, aitem, tvb, pinfo, info, fd);
        show_findings(at, aitem, tvb, pinfo, info, fd);
        show_orphan(at, aitem, tvb, pinfo, info, fd);
        show_reassembly(tvb, pinfo, eglink_tree, info, fd);
    }
    queue_tap(pinfo, info, fd);
}

/* ---------------------------------------------------------------------- */

void
eglink_analysis_register(int proto, module_t *prefs)
{
    static hf_register_info hf[] = {
        { &hf_analysis,
          { "Analysis", "eglink.analysis", FT_NONE, BASE_NONE, NULL, 0x0,
            "Conversation analysis of this packet within its BU", HFILL } },
        { &hf_bu_stream,
          { "BU stream index", "eglink.analysis.bu_stream", FT_UINT32, BASE_DEC, NULL, 0x0,
            "Number of the BU (origin and address, on its group or address pair and input "
            "port) this packet belongs to, from 0 in order of appearance; absent on a "
            "controller packet whose BU is not known yet", HFILL } },
        { &hf_bu_origin,
          { "BU origin", "eglink.analysis.bu_origin", FT_UINT16, BASE_HEX, NULL, 0x0,
            "Unique ID of the BU this packet belongs to, learned from its VRPI/VRCI/VRAI "
            "(also on the packets of the machine controller joined to it, which carry "
            "origin 0; on a controller joined later, from the second pass on)", HFILL } },
        { &hf_device,
          { "Device", "eglink.analysis.device", FT_STRING, BASE_NONE, NULL, 0x0,
            "The BU this packet belongs to: its origin (0x1001), or \"BU not known\" on the "
            "packets of a controller not joined to a BU", HFILL } },
        { &hf_joined_alone,
          { "Joined for being alone", "eglink.analysis.joined_alone", FT_BOOLEAN, BASE_NONE, NULL, 0x0,
            "A controller packet joined to its BU only because the two are the only controller "
            "and the only BU of the channel so far (no command acknowledged between them yet); "
            "a second BU or controller there withdraws it", HFILL } },
        { &hf_expected_serial,
          { "Expected serial", "eglink.analysis.expected_serial", FT_UINT16, BASE_DEC, NULL, 0x0,
            "Serial that follows the previous packet of the same sender", HFILL } },
        { &hf_lost,
          { "Lost packets", "eglink.analysis.lost", FT_UINT16, BASE_DEC, NULL, 0x0,
            "Packets of this sender missing just before this one (serial gap)", HFILL } },
        { &hf_repeat_of,
          { "Repeat of frame", "eglink.analysis.repeat_of", FT_FRAMENUM, BASE_NONE,
            FRAMENUM_TYPE(FT_FRAMENUM_DUP_ACK), 0x0,
            "Earlier frame with the same sender and serial", HFILL } },
        { &hf_time_since_prev_vrpi,
          { "Time since previous VRPI", "eglink.analysis.time_since_prev_vrpi", FT_RELATIVE_TIME,
            BASE_NONE, NULL, 0x0, "Time since the previous VRPI of this BU", HFILL } },
        { &hf_time_since_prev_vrpo,
          { "Time since previous VRPO", "eglink.analysis.time_since_prev_vrpo", FT_RELATIVE_TIME,
            BASE_NONE, NULL, 0x0, "Time since the previous VRPO to this BU", HFILL } },
        { &hf_retransmission_of,
          { "Retransmission of frame", "eglink.analysis.retransmission_of", FT_FRAMENUM, BASE_NONE,
            FRAMENUM_TYPE(FT_FRAMENUM_RETRANS_PREV), 0x0,
            "First transmission of this command (same Command ID)", HFILL } },
        { &hf_ack_in,
          { "Acknowledged in frame", "eglink.analysis.ack_in", FT_FRAMENUM, BASE_NONE,
            FRAMENUM_TYPE(FT_FRAMENUM_RESPONSE), 0x0,
            "First VRAO (for a VRCI) or VRAI (for a VRCO) acknowledging this command", HFILL } },
        { &hf_ack_to,
          { "Acknowledges frame", "eglink.analysis.ack_to", FT_FRAMENUM, BASE_NONE,
            FRAMENUM_TYPE(FT_FRAMENUM_ACK), 0x0,
            "First transmission of the command this packet acknowledges", HFILL } },
        { &hf_ack_time,
          { "Acknowledgement time", "eglink.analysis.ack_time", FT_RELATIVE_TIME, BASE_NONE,
            NULL, 0x0, "Time from the first transmission of the command to this acknowledgement",
            HFILL } },
        { &hf_failed_command,
          { "Unacknowledged command", "eglink.analysis.failed_command", FT_FRAMENUM, BASE_NONE,
            FRAMENUM_TYPE(FT_FRAMENUM_NONE), 0x0,
            "Command whose acknowledgement deadline passed before this packet", HFILL } },
        { &hf_deadline_in,
          { "Acknowledgement deadline passed in frame", "eglink.analysis.deadline_in", FT_FRAMENUM,
            BASE_NONE, FRAMENUM_TYPE(FT_FRAMENUM_NONE), 0x0,
            "First packet of the BU or its controller after this command's acknowledgement deadline "
            "passed unacknowledged (second pass and GUI)", HFILL } },
        { &hf_incomplete_burst,
          { "Incomplete VRPO burst", "eglink.analysis.incomplete_burst", FT_FRAMENUM, BASE_NONE,
            FRAMENUM_TYPE(FT_FRAMENUM_NONE), 0x0,
            "First packet of a split VRPO burst that cannot be reassembled", HFILL } },
        { &hf_last_vrpi,
          { "Last VRPI before the gap", "eglink.analysis.last_vrpi", FT_FRAMENUM, BASE_NONE,
            FRAMENUM_TYPE(FT_FRAMENUM_NONE), 0x0,
            "The BU's VRPI before a VRPI gap (eglink.analysis.vrpi_gap, vrpi_missing)", HFILL } },
        { &hf_last_vrpo,
          { "Last VRPO before the gap", "eglink.analysis.last_vrpo", FT_FRAMENUM, BASE_NONE,
            FRAMENUM_TYPE(FT_FRAMENUM_NONE), 0x0,
            "The controller's VRPO before a VRPO gap (eglink.analysis.vrpo_gap, vrpo_missing)", HFILL } },

        { &hf_corrupted_in,
          { "Serial arrived corrupted in frame", "eglink.analysis.corrupted_in", FT_FRAMENUM, BASE_NONE,
            FRAMENUM_TYPE(FT_FRAMENUM_NONE), 0x0,
            "A packet of this sender's serial gap that arrived with a bad CRC or size: not lost",
            HFILL } },
        { &hf_expected_port,
          { "Expected UDP port", "eglink.analysis.expected_port", FT_UINT16, BASE_DEC, NULL, 0x0,
            "The port a controller packet sent to another port belongs on: the BU's input port + 2",
            HFILL } },
        { &hf_time_backwards_after,
          { "Time went backwards after frame", "eglink.analysis.time_backwards_after", FT_FRAMENUM,
            BASE_NONE, FRAMENUM_TYPE(FT_FRAMENUM_NONE), 0x0,
            "The EG-Link packet before a clock step back, newer than this one", HFILL } },

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
        &ett_analysis,
        &ett_fragment,
        &ett_fragments,
    };

    /* Severities and groups as docs/findings.md "How findings read" says: a VRPI or
     * VRPO gap forces the safe state (error); lost, repeated, unacknowledged
     * and late packets and a shared group are warnings; state changes,
     * retransmissions and restarts notes; commands and acknowledgements chat. */
    static ei_register_info ei[] = {
        { &ei_serial_gap,
          { "eglink.analysis.serial_gap", PI_SEQUENCE, PI_WARN,
            "Packets lost: serial gap", EXPFILL } },
        { &ei_serial_repeat,
          { "eglink.analysis.serial_repeat", PI_SEQUENCE, PI_WARN,
            "Repeated packet: serial already received", EXPFILL } },
        { &ei_serial_restart,
          { "eglink.analysis.serial_restart", PI_SEQUENCE, PI_NOTE,
            "Serial jumped back: the sender restarted", EXPFILL } },
        { &ei_vrpi_gap,
          { "eglink.analysis.vrpi_gap", PI_SEQUENCE, PI_ERROR,
            "VRPI gap longer than the threshold", EXPFILL } },
        { &ei_vrpo_gap,
          { "eglink.analysis.vrpo_gap", PI_SEQUENCE, PI_ERROR,
            "VRPO gap longer than the threshold", EXPFILL } },
        { &ei_vrpi_missing,
          { "eglink.analysis.vrpi_missing", PI_SEQUENCE, PI_ERROR,
            "No VRPI from the BU for longer than the threshold", EXPFILL } },
        { &ei_vrpo_missing,
          { "eglink.analysis.vrpo_missing", PI_SEQUENCE, PI_ERROR,
            "No VRPO to the BU for longer than the threshold", EXPFILL } },
        { &ei_retransmission,
          { "eglink.analysis.retransmission", PI_SEQUENCE, PI_NOTE,
            "Command retransmission (same Command ID)", EXPFILL } },
        { &ei_vrci_unacked,
          { "eglink.analysis.vrci_unacked", PI_SEQUENCE, PI_WARN,
            "VRCI not acknowledged in time: the command failed", EXPFILL } },
        { &ei_vrco_unacked,
          { "eglink.analysis.vrco_unacked", PI_SEQUENCE, PI_WARN,
            "VRCO not acknowledged in time", EXPFILL } },
        { &ei_vrci_deadline,
          { "eglink.analysis.vrci_deadline", PI_SEQUENCE, PI_NOTE,
            "Deadline of a VRCI passed with no VRAO", EXPFILL } },
        { &ei_vrco_deadline,
          { "eglink.analysis.vrco_deadline", PI_SEQUENCE, PI_NOTE,
            "Deadline of a VRCO passed with no VRAI", EXPFILL } },
        { &ei_late_ack,
          { "eglink.analysis.late_ack", PI_SEQUENCE, PI_WARN,
            "Acknowledgement after the deadline", EXPFILL } },
        { &ei_unknown_ack,
          { "eglink.analysis.unknown_ack", PI_SEQUENCE, PI_CHAT,
            "Acknowledges a command that is not in the capture", EXPFILL } },
        { &ei_bu_state_changed,
          { "eglink.analysis.bu_state_changed", PI_SEQUENCE, PI_NOTE,
            "BU state changed", EXPFILL } },
        { &ei_origin_changed,
          { "eglink.analysis.origin_changed", PI_SEQUENCE, PI_WARN,
            "Another origin from the same BU address", EXPFILL } },
        { &ei_burst_incomplete,
          { "eglink.analysis.burst_incomplete", PI_REASSEMBLE, PI_WARN,
            "Split VRPO burst incomplete", EXPFILL } },
        { &ei_burst_size,
          { "eglink.analysis.burst_size", PI_REASSEMBLE, PI_WARN,
            "VRPO burst size differs from the periodic data size preference", EXPFILL } },
        { &ei_shared_group,
          { "eglink.analysis.shared_group", PI_SEQUENCE, PI_WARN,
            "Several BUs or controllers on one group and port", EXPFILL } },
        { &ei_command,
          { "eglink.analysis.command", PI_SEQUENCE, PI_CHAT,
            "New command (first transmission)", EXPFILL } },
        { &ei_ack,
          { "eglink.analysis.ack", PI_SEQUENCE, PI_CHAT,
            "Command acknowledged in time", EXPFILL } },
        { &ei_serial_corrupted,
          { "eglink.analysis.serial_corrupted", PI_SEQUENCE, PI_NOTE,
            "A serial of the gap arrived with a bad CRC or size: not lost", EXPFILL } },
        { &ei_wrong_port,
          { "eglink.analysis.wrong_port", PI_PROTOCOL, PI_WARN,
            "Controller packet on another UDP port than the BU's input port + 2", EXPFILL } },
        { &ei_time_backwards,
          { "eglink.analysis.time_backwards", PI_SEQUENCE, PI_WARN,
            "Time went backwards (clock step): rules restart here", EXPFILL } },
        { &ei_vrpo_number,
          { "eglink.analysis.vrpo_number", PI_SEQUENCE, PI_WARN,
            "VRPO packet number breaks the controller's numbering (TS-0006 4.2)", EXPFILL } },
        { &ei_vrpo_interval,
          { "eglink.analysis.vrpo_interval", PI_SEQUENCE, PI_NOTE,
            "VRPO interval outside the recommended 50 to 200 ms (TS-0006 5.1.2)", EXPFILL } },
        { &ei_burst_spread,
          { "eglink.analysis.burst_spread", PI_SEQUENCE, PI_NOTE,
            "Packets of a split VRPO burst spread out (TS-0006 5.1.2)", EXPFILL } },
        { &ei_vrpo_not_full,
          { "eglink.analysis.vrpo_not_full", PI_PROTOCOL, PI_WARN,
            "A VRPO packet that is not the last of its burst is not full (TS-0006 4.2)", EXPFILL } },
        { &ei_resend_interval,
          { "eglink.analysis.resend_interval", PI_SEQUENCE, PI_NOTE,
            "Command resent at another interval than 100 ms (TS-0006 5.1.3, 5.1.4)", EXPFILL } },
        { &ei_not_resent,
          { "eglink.analysis.not_resent", PI_SEQUENCE, PI_WARN,
            "Unacknowledged command not resent within 100 ms (TS-0006 5.1.3, 5.1.4)", EXPFILL } },
        { &ei_resent_after_ack,
          { "eglink.analysis.resent_after_ack", PI_SEQUENCE, PI_NOTE,
            "Command resent after its acknowledgement (TS-0006 5.1.3, 5.1.4)", EXPFILL } },
        { &ei_resent_after_deadline,
          { "eglink.analysis.resent_after_deadline", PI_SEQUENCE, PI_NOTE,
            "Command resent after its acknowledgement timeout (TS-0006 5.1.3, 5.1.4)", EXPFILL } },
        { &ei_command_id_sequence,
          { "eglink.analysis.command_id_sequence", PI_SEQUENCE, PI_WARN,
            "Command ID not the previous one + 1 (TS-0006 4.3, 4.5)", EXPFILL } },
        { &ei_revision_ignored,
          { "eglink.analysis.revision_ignored", PI_PROTOCOL, PI_NOTE,
            "Packet of another header revision kept out of the analysis (TS-0006 5.1.5)", EXPFILL } },
        { &ei_join_withdrawn,
          { "eglink.analysis.join_withdrawn", PI_SEQUENCE, PI_NOTE,
            "A controller joined to its BU only for being alone with it on the channel: no longer, "
            "with a second BU or controller there", EXPFILL } },
        { &ei_not_joined,
          { "eglink.analysis.not_joined", PI_SEQUENCE, PI_NOTE,
            "Controller packet on a port where no BU has been seen: not joined to a BU yet (one pass)",
            EXPFILL } },
    };
    expert_module_t *expert;

    proto_eglink = proto;
    proto_register_field_array(proto, hf, array_length(hf));
    proto_register_subtree_array(ett, array_length(ett));
    expert = expert_register_protocol(proto);
    expert_register_field_array(expert, ei, array_length(ei));

    prefs_register_uint_preference(prefs, "vrpi_gap_ms", "VRPI gap threshold (ms)",
        "A VRPI later than this after the previous one of its BU is flagged; the machine "
        "controller should flag an error after e.g. 500 ms (the BU sends every 125 ms)",
        10, &pref_vrpi_gap_ms);
    prefs_register_uint_preference(prefs, "vrpo_gap_ms", "VRPO gap threshold (ms)",
        "A VRPO later than this after the previous one to its BU is flagged; the BU flags an "
        "error after 2000 ms and, with an RU armed, opens the ES-Link relays",
        10, &pref_vrpo_gap_ms);
    prefs_register_uint_preference(prefs, "vrci_ack_timeout_ms", "VRCI acknowledgement timeout (ms)",
        "A VRCI not acknowledged by a VRAO within this time failed (the BU gives up after 2000 ms)",
        10, &pref_vrci_ack_timeout_ms);
    prefs_register_uint_preference(prefs, "vrco_ack_timeout_ms", "VRCO acknowledgement timeout (ms)",
        "A VRCO not acknowledged by a VRAI within this time is flagged",
        10, &pref_vrco_ack_timeout_ms);
    prefs_register_uint_preference(prefs, "periodic_size", "Periodic data size (bytes, 0 = unknown)",
        "Configured size of the VRPO periodic data; a split burst ends when it reaches this size. "
        "0: a burst ends with a packet shorter than 488 bytes or when the next burst starts",
        10, &pref_periodic_size);
    prefs_register_uint_preference(prefs, "resend_tolerance_ms", "Command resend tolerance (ms)",
        "A VRCI or VRCO is resent every 100 ms until acknowledged (TS-0006 5.1.3, 5.1.4): a resend "
        "further than this from 100 ms after the previous transmission is noted, and an "
        "unacknowledged command not resent within 100 ms + this is flagged",
        10, &pref_resend_tolerance_ms);
    prefs_register_uint_preference(prefs, "burst_spread_ms", "VRPO burst spread limit (ms)",
        "The packets of a split VRPO are sent without delay (TS-0006 5.1.2): a packet of a burst "
        "later than this after the one before it is noted",
        10, &pref_burst_spread_ms);
    prefs_register_bool_preference(prefs, "reassemble_vrpo", "Reassemble split VRPO bursts",
        "Reassemble the periodic data of VRPO bursts split into several packets",
        &pref_reassemble);

    eglink_chans = wmem_map_new_autoreset(wmem_epan_scope(), wmem_file_scope(),
                                          eglink_chan_hash, eglink_chan_equal);
    eglink_groups = wmem_map_new_autoreset(wmem_epan_scope(), wmem_file_scope(),
                                           eglink_chan_hash, eglink_chan_equal);
    register_init_routine(eglink_analysis_init);
    reassembly_table_register(&eglink_reassembly_table, &addresses_ports_reassembly_table_functions);
    eglink_tap = register_tap("eglink");
    eglink_stats_register();
}
