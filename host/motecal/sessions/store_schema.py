"""The motecal database's schema: its version, its tables as migrations, the
link and line counters, and how a motecal database is recognised.

Every backend (store_sqlite.py, store_postgres.py, store_mysql.py) makes the
same tables from ``MIGRATIONS``; ``Store`` (store.py) runs the ones a
database lacks when it is opened for writing.
"""
from __future__ import annotations

from .session import COLUMNS

SCHEMA_VERSION = 7

SAMPLE_COLUMNS = ("session", "mote", "seq", "t", "label", "flags") + COLUMNS

# Per-mote link counters (link_stats) and per-line counters (line_stats):
# name -> meaning.  The logger fills them; docs/log.md (the database) lists them.
LINK_COUNTERS = {
    "frames": "sample messages received from this mote",
    "samples": "records stored",
    "lost": "records missing by sequence number (gaps not filled later)",
    "duplicates": "records received again (dropped)",
    "reordered": "records that arrived late and filled a gap",
    "restarts": "sequence number jumped back: mote restarted",
    "rejected": "frames rejected: sequence number implausible, not confirmed",
    "first_seq": "first unwrapped sequence number",
    "last_seq": "last unwrapped sequence number",
    "status_msgs": "mote status messages received",
    "mote_dropped": "mote counter: samples lost, send queue full",
    "mote_send_fail": "mote counter: radio sends that failed",
    "mote_i2c_errors": "mote counter: sensor reads that failed",
    "mote_late": "mote counter: periods whose read was late",
    "cal_version": "calibration version in force on the mote",
    "cal_sensors": "sensors corrected on the mote (bit mask)",
    "mote_i2c_nacks": "mote counter: I2C operations a chip did not acknowledge",
    "mote_bus_resets": "mote counter: bus clears run (after a hung I2C operation was aborted, and each retry while the bus is down)",
    "mote_chip_reinits": "mote counter: chips found with reset registers, configured again",
}
LINE_COUNTERS = {
    "frames": "good serial frames",
    "crc_errors": "frames with a bad CRC (corrupt or truncated)",
    "bad_frames": "frames with a good CRC but a wrong length or protocol byte",
    "garbage_bytes": "bytes outside any frame",
    "cut_off": "frames cut short by the end of the line (port closed, logger stopped)",
    "unknown_msgs": "frames of an unknown AM type or dispatch byte",
    "bad_msgs": "known AM type with a wrong payload length",
    "acks": "ack frames (0x43)",
    "disconnects": "times the port went away",
    "gap_s": "seconds without a port",
    "bs_status_msgs": "BaseStation status messages",
    "bs_radio_rx": "BaseStation counter: packets from the radio",
    "bs_radio_drops": "BaseStation counter: radio->serial queue full",
    "bs_serial_rx": "BaseStation counter: packets from the serial line",
    "bs_serial_drops": "BaseStation counter: serial->radio queue full",
    "bs_radio_fail": "BaseStation counter: radio sends failed",
    "bs_serial_fail": "BaseStation counter: serial sends failed",
}


# sqlite's PRAGMA application_id of a motecal database ("MCAL"): set on
# create, and on the first write to an older motecal database recognised by
# SIGNATURE (its tables and their columns).
APPLICATION_ID = 0x4D43414C
SIGNATURE = {
    "schema_version": {"version"},
    "sessions": {"id", "name", "kind", "started", "ended", "scales", "chips", "meta"},
    "samples": {"session", "mote", "seq", "t", "label", "flags", "ax", "ay", "az", "gx", "gy",
                "gz", "mx", "my", "mz"},
    "calibrations": {"id", "session", "mote", "created", "cal"},
}
SIGNATURE_SINCE = {2: ("link_stats", "line_stats", "events"), 5: ("writers", "sample_conflicts"),
                   6: ("temps",), 7: ("diagnoses",)}


# --------------------------------------------------------------------------
# Schema and migrations.  Each migration is a list of statements; {int16},
# {real}, {id_pk}, {wr} are filled in per backend (Backend.types).  A released
# migration is never edited and is written out literally, never built from
# LINK_COUNTERS or LINE_COUNTERS: those grow, and a migration that follows
# them would make a later migration's column twice on a fresh database.  To
# change the schema add the next migration and bump SCHEMA_VERSION
# (docs/CONTRIBUTING.md, "A store counter").
# --------------------------------------------------------------------------
MIGRATIONS = {
    1: [
        "CREATE TABLE schema_version (version INTEGER NOT NULL)",
        """CREATE TABLE sessions (
             id {id_pk},
             name TEXT NOT NULL UNIQUE,
             kind TEXT NOT NULL,
             started {real} NOT NULL,
             ended {real},
             source TEXT,
             rate_hz {real},
             notes TEXT,
             scales TEXT NOT NULL,
             chips TEXT NOT NULL,
             meta TEXT NOT NULL)""",
        """CREATE TABLE samples (
             session BIGINT NOT NULL,
             mote INTEGER NOT NULL,
             seq BIGINT NOT NULL,
             t {real},
             label TEXT NOT NULL DEFAULT '',
             flags SMALLINT NOT NULL DEFAULT 0,
             ax {int16}, ay {int16}, az {int16},
             gx {int16}, gy {int16}, gz {int16},
             mx {int16}, my {int16}, mz {int16},
             PRIMARY KEY (session, mote, seq)){wr}""",
        """CREATE TABLE calibrations (
             id {id_pk},
             session BIGINT NOT NULL,
             mote INTEGER NOT NULL,
             created {real} NOT NULL,
             cal TEXT NOT NULL)""",
        "CREATE INDEX calibrations_session ON calibrations (session, mote, id)",
    ],
    2: [
        """CREATE TABLE link_stats (
             session BIGINT NOT NULL,
             mote INTEGER NOT NULL,
             frames BIGINT NOT NULL DEFAULT 0,
             samples BIGINT NOT NULL DEFAULT 0,
             lost BIGINT NOT NULL DEFAULT 0,
             duplicates BIGINT NOT NULL DEFAULT 0,
             reordered BIGINT NOT NULL DEFAULT 0,
             restarts BIGINT NOT NULL DEFAULT 0,
             rejected BIGINT NOT NULL DEFAULT 0,
             first_seq BIGINT NOT NULL DEFAULT 0,
             last_seq BIGINT NOT NULL DEFAULT 0,
             status_msgs BIGINT NOT NULL DEFAULT 0,
             mote_dropped BIGINT NOT NULL DEFAULT 0,
             mote_send_fail BIGINT NOT NULL DEFAULT 0,
             mote_i2c_errors BIGINT NOT NULL DEFAULT 0,
             mote_late BIGINT NOT NULL DEFAULT 0,
             cal_version BIGINT NOT NULL DEFAULT 0,
             cal_sensors BIGINT NOT NULL DEFAULT 0,
             updated {real},
             PRIMARY KEY (session, mote))""",
        """CREATE TABLE line_stats (
             session BIGINT PRIMARY KEY,
             frames BIGINT NOT NULL DEFAULT 0,
             crc_errors BIGINT NOT NULL DEFAULT 0,
             bad_frames BIGINT NOT NULL DEFAULT 0,
             garbage_bytes BIGINT NOT NULL DEFAULT 0,
             unknown_msgs BIGINT NOT NULL DEFAULT 0,
             bad_msgs BIGINT NOT NULL DEFAULT 0,
             acks BIGINT NOT NULL DEFAULT 0,
             disconnects BIGINT NOT NULL DEFAULT 0,
             gap_s {real} NOT NULL DEFAULT 0,
             bs_status_msgs BIGINT NOT NULL DEFAULT 0,
             bs_radio_rx BIGINT NOT NULL DEFAULT 0,
             bs_radio_drops BIGINT NOT NULL DEFAULT 0,
             bs_serial_rx BIGINT NOT NULL DEFAULT 0,
             bs_serial_drops BIGINT NOT NULL DEFAULT 0,
             bs_radio_fail BIGINT NOT NULL DEFAULT 0,
             bs_serial_fail BIGINT NOT NULL DEFAULT 0,
             updated {real})""",
        """CREATE TABLE events (
             session BIGINT NOT NULL,
             t {real} NOT NULL,
             kind TEXT NOT NULL,
             mote INTEGER,
             detail TEXT NOT NULL DEFAULT '')""",
        "CREATE INDEX events_session ON events (session, t)",
    ],
    # 3: frames cut short by the end of the line
    3: ["ALTER TABLE line_stats ADD COLUMN cut_off BIGINT NOT NULL DEFAULT 0"],
    # 4: the mote's I2C fault counters
    4: ["ALTER TABLE link_stats ADD COLUMN mote_i2c_nacks BIGINT NOT NULL DEFAULT 0",
        "ALTER TABLE link_stats ADD COLUMN mote_bus_resets BIGINT NOT NULL DEFAULT 0",
        "ALTER TABLE link_stats ADD COLUMN mote_chip_reinits BIGINT NOT NULL DEFAULT 0"],
    # 5: several writers to one session (docs/guarantees.md, "several writers"):
    # each live writer's own row of counts, and every sample a writer received
    # under a key already stored with other values, kept whole
    5: [
        """CREATE TABLE writers (
             session BIGINT NOT NULL,
             writer TEXT NOT NULL,
             source TEXT,
             started {real} NOT NULL,
             updated {real},
             ended {real},
             stored BIGINT NOT NULL DEFAULT 0,
             duplicates BIGINT NOT NULL DEFAULT 0,
             conflicts BIGINT NOT NULL DEFAULT 0,
             PRIMARY KEY (session, writer))""",
        """CREATE TABLE sample_conflicts (
             session BIGINT NOT NULL,
             mote INTEGER NOT NULL,
             seq BIGINT NOT NULL,
             t {real},
             flags SMALLINT NOT NULL DEFAULT 0,
             ax {int16}, ay {int16}, az {int16},
             gx {int16}, gy {int16}, gz {int16},
             mx {int16}, my {int16}, mz {int16},
             writer TEXT NOT NULL,
             found {real} NOT NULL)""",
        "CREATE INDEX sample_conflicts_key ON sample_conflicts (session, mote, seq)",
    ],
    # 6: the board temperature (issue 16).  One row per reading: a mote's
    # temperature message (seq = unwrapped sequence number of the newest
    # sample in its sum, count = readings averaged, t = host time it came)
    # or an imported row's temperature (count 1, the row's seq); temp_c is
    # the mean in degrees C.  SessionData.temp is interpolated from these
    # when a session is loaded (sessions/temperature.py).
    6: [
        """CREATE TABLE temps (
             session BIGINT NOT NULL,
             mote INTEGER NOT NULL,
             seq BIGINT NOT NULL,
             t {real},
             temp_c {real} NOT NULL,
             count INTEGER NOT NULL DEFAULT 1,
             PRIMARY KEY (session, mote, seq)){wr}""",
    ],
    # 7: a session's diagnoses (issue 13, closing the loop): what ``motecal
    # diagnose`` found on one mote's data, kept with the session so that
    # ``calibrate`` uses it by default.  ``tool`` is the motecal version that
    # made it, ``data_key`` the fingerprint of the rows it saw
    # (sessions.fingerprint): a diagnosis of other data or another version
    # is never used silently.
    7: [
        """CREATE TABLE diagnoses (
             id {id_pk},
             session BIGINT NOT NULL,
             mote INTEGER NOT NULL,
             created {real} NOT NULL,
             tool TEXT NOT NULL,
             data_key TEXT NOT NULL,
             diagnosis TEXT NOT NULL)""",
        "CREATE INDEX diagnoses_session ON diagnoses (session, mote, id)",
    ],
}
