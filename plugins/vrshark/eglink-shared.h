/* eglink-shared.h
 * What the files of the EG-Link analysis share (twin: lua/vrshark/eglink_shared.luam):
 * the state of channels, BUs, controllers, commands and bursts, the record
 * of a frame and its findings, the preferences, and the functions one file
 * calls in another. eglink-analysis.c walks a packet through them; the
 * public side (the dissector, the statistics) is eglink-analysis.h.
 *
 *   eglink-analysis.c   the walk of a packet, preferences, init, tap
 *   eglink-records.c    records by frame number, findings lists
 *   eglink-channels.c   channels, BUs, controllers, who talks to whom
 *   eglink-serials.c    serial numbers: lost, repeated, restarted
 *   eglink-timing.c     periodic intervals, gaps, deadlines, clock steps
 *   eglink-commands.c   commands, acknowledgements, resends
 *   eglink-bursts.c     VRPO bursts and their reassembly
 *   eglink-findings.c   the tree, expert info and Info tags of a record
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef EGLINK_SHARED_H
#define EGLINK_SHARED_H

#include "eglink-analysis.h"
#include "eglink-compat.h"

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

/* Preferences (eglink-analysis.c registers them) */
extern guint eglink_pref_vrpi_gap_ms;
extern guint eglink_pref_vrpo_gap_ms;
extern guint eglink_pref_vrci_ack_timeout_ms;
extern guint eglink_pref_vrco_ack_timeout_ms;
extern guint eglink_pref_periodic_size;
extern eglink_pref_bool_t eglink_pref_reassemble;
/* TS-0006 5.1.3, 5.1.4: commands are resent every 100 ms until acknowledged. */
#define EGLINK_RESEND_INTERVAL_MS 100
extern guint eglink_pref_resend_tolerance_ms;
/* TS-0006 5.1.2: VRPO every 50 to 200 ms (recommended); a split burst without delay. */
#define EGLINK_VRPO_INTERVAL_MIN_MS 50
#define EGLINK_VRPO_INTERVAL_MAX_MS 200
extern guint eglink_pref_burst_spread_ms;

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

/* File scope: the BUs and controllers by index (eglink-channels.c), the
 * reassembly IDs given (eglink-bursts.c), the acknowledgement of the frame
 * being analysed that waits for its stored record (eglink-commands.c). */
extern wmem_array_t *eglink_bu_by_index;
extern wmem_array_t *eglink_ctrl_by_index;
extern guint32 eglink_burst_count;
extern eglink_orphan_ack_t *eglink_orphan_pending;

static inline gint64
ns_signed(const nstime_t *later, const nstime_t *earlier)
{
    nstime_t d;

    nstime_delta(&d, later, earlier);
    return (gint64)d.secs * 1000000000 + d.nsecs;
}

/* A time between two packets, never below 0: a clock step back restarts
 * every time the analysis measures (check_clock()), and packets a little
 * out of order count as simultaneous. */
static inline gint64
ns_between(const nstime_t *later, const nstime_t *earlier)
{
    return MAX(0, ns_signed(later, earlier));
}

static inline gint64
ms_to_ns(guint ms)
{
    return (gint64)ms * 1000000;
}

static inline gboolean
eglink_is_input(eglink_type_t type)
{
    return type == EGLINK_TYPE_VRPI || type == EGLINK_TYPE_VRCI || type == EGLINK_TYPE_VRAI;
}

/* eglink-records.c */
void eglink_records_init(void);
void eglink_records_register(int proto);
void eglink_frame_renumbered(packet_info *pinfo);
eglink_frame_t *eglink_frame_store(packet_info *pinfo, guint32 key, guint16 serial, const eglink_frame_t *fd);
const eglink_frame_t *eglink_frame_fetch(packet_info *pinfo, guint32 key, guint16 serial, eglink_frame_t *buf);
void add_finding(eglink_frame_t *fd, eglink_finding_kind_t kind, guint32 frame, guint32 value, gint64 ns);
const eglink_finding_t *find_finding(const eglink_frame_t *fd, eglink_finding_kind_t kind);

/* eglink-channels.c */
void eglink_channels_init(void);
void eglink_channels_register(void);
eglink_chan_t *eglink_bu_chan(packet_info *pinfo, guint32 *expected);
eglink_chan_t *eglink_ctrl_chan(packet_info *pinfo, guint32 *expected);
eglink_bu_t *eglink_bu_lookup(packet_info *pinfo, eglink_chan_t *chan, guint16 origin);
eglink_ctrl_t *eglink_ctrl_lookup(packet_info *pinfo, eglink_chan_t *chan);
void join_if_alone(eglink_chan_t *chan, eglink_frame_t *fd, packet_info *pinfo);
void check_shared(eglink_chan_t *chan, eglink_sender_t *s, eglink_frame_t *fd);
const eglink_frame_t *frame_view(const eglink_frame_t *fd, eglink_frame_t *buf);

/* eglink-serials.c */
void remember_corrupted(eglink_sender_t *s, packet_info *pinfo, const eglink_info_t *info);
guint serial_lost(const eglink_frame_t *fd, guint16 serial);
void track_serial(eglink_sender_t *s, eglink_frame_t *fd, packet_info *pinfo, const eglink_info_t *info,
                  gboolean input);
void track_revision(eglink_sender_t *s, eglink_frame_t *fd, packet_info *pinfo, const eglink_info_t *info);

/* eglink-timing.c */
void eglink_timing_init(void);
void check_clock(packet_info *pinfo, eglink_frame_t *fd);
void check_deadlines(eglink_chan_t *chan, eglink_bu_t *bu, eglink_ctrl_t *sender, eglink_frame_t *fd,
                     packet_info *pinfo, const eglink_info_t *info);
void track_interval(eglink_sender_t *s, eglink_frame_t *fd, packet_info *pinfo, guint threshold_ms,
                    eglink_finding_kind_t gap);
void track_vrpi(eglink_bu_t *bu, eglink_frame_t *fd, packet_info *pinfo, const eglink_info_t *info);

/* eglink-commands.c */
void check_commands(eglink_sender_t *s, eglink_frame_t *fd, packet_info *pinfo, int dir, gint32 own_id);
void track_command(eglink_sender_t *s, eglink_frame_t *fd, packet_info *pinfo, int dir, guint16 command_id);
gboolean waits_for_ack(const eglink_cmd_t *cmd);
eglink_cmd_t *vrci_acknowledged(eglink_ctrl_t *ctrl, guint16 command_id);
eglink_cmd_t *vrco_acknowledged(eglink_bu_t *bu, guint16 command_id);
void track_ack(eglink_cmd_t *cmd, eglink_frame_t *fd, packet_info *pinfo, int dir, guint16 command_id);
void remember_orphan_ack(eglink_ctrl_t *ctrl, packet_info *pinfo, guint16 command_id);
void match_orphan_acks(eglink_ctrl_t *ctrl);

/* eglink-bursts.c */
void eglink_bursts_init(void);
void eglink_bursts_register(int proto);
void track_burst(eglink_burst_t *b, eglink_frame_t *fd, packet_info *pinfo, const eglink_info_t *info);
void show_reassembly(tvbuff_t *tvb, packet_info *pinfo, proto_tree *tree, const eglink_info_t *info,
                     const eglink_frame_t *fd);

/* eglink-findings.c */
void eglink_findings_register(int proto);
void show_frame(tvbuff_t *tvb, packet_info *pinfo, proto_tree *eglink_tree, const eglink_info_t *info,
                const eglink_frame_t *fd);

#endif /* EGLINK_SHARED_H */
