"""SIGTERM, SIGINT, SIGHUP: end every process the report started, then itself.

The report runs worker processes, and each runs a tshark (through a wrapper
such as tools/tshark). A CI timeout that sends SIGTERM to the report alone
must not leave them reading a capture to its end, nor a worker blocked on a
FIFO without a writer. The handler is installed before the workers fork, so
each worker runs it too (ending its own tshark). The processes are found as
descendants in /proc, not as a process group: the report shares its group
with the shell that started it and must not signal that.
"""
import os
import signal
import time

SIGNALS = (signal.SIGTERM, signal.SIGINT, signal.SIGHUP)
GRACE = 0.5   # s between SIGTERM and SIGKILL for a process that does not end


def install():
    for signum in SIGNALS:
        signal.signal(signum, _stop)


def leave_to_parent():
    """In a worker: Ctrl-C and a hangup reach the whole terminal group at once;
    the parent ends the worker (SIGTERM) and this worker its tshark. A worker
    that ended on its own first would look like a broken pool to the parent.
    (A no-op handler rather than SIG_IGN, which tshark would inherit.)"""
    for signum in (signal.SIGINT, signal.SIGHUP):
        signal.signal(signum, _ignore)


def _ignore(signum, frame):
    pass


def descendants(root):
    """Every process below root (pids), from /proc/*/stat."""
    children = {}
    try:
        entries = os.listdir("/proc")
    except OSError:
        return []
    for entry in entries:
        if not entry.isdigit():
            continue
        try:
            with open("/proc/%s/stat" % entry, "rb") as f:
                data = f.read()
        except OSError:
            continue
        ppid = int(data[data.rfind(b")") + 2:].split()[1])   # pid (comm) state ppid ...
        children.setdefault(ppid, []).append(int(entry))
    found, todo = [], [root]
    while todo:
        for child in children.get(todo.pop(), []):
            found.append(child)
            todo.append(child)
    return found


def alive(pid):
    try:
        if os.waitpid(pid, os.WNOHANG)[0] == pid:
            return False    # a worker of ours, now reaped
    except ChildProcessError:
        pass                # a grandchild: its own parent reaps it
    try:
        with open("/proc/%d/stat" % pid, "rb") as f:
            data = f.read()
    except OSError:
        return False
    return data[data.rfind(b")") + 2:][:1] != b"Z"


def signal_all(pids, signum):
    for pid in pids:
        try:
            os.kill(pid, signum)
        except OSError:
            pass


def _stop(signum, frame):
    for s in SIGNALS:
        signal.signal(s, signal.SIG_IGN)
    deadline = time.monotonic() + GRACE
    left = descendants(os.getpid())
    while left and time.monotonic() < deadline:
        signal_all(left, signal.SIGTERM)
        time.sleep(0.02)
        # (a worker may have started its tshark meanwhile)
        left = [p for p in set(left) | set(descendants(os.getpid())) if alive(p)]
    signal_all(left, signal.SIGKILL)
    while left and time.monotonic() < deadline + GRACE:
        time.sleep(0.01)
        left = [p for p in left if alive(p)]
    os._exit(128 + signum)
