"""Shared plumbing of the device emulators: a pseudo-terminal pair, advertising its slave path
(symbolic link and/or link file, both removed again on exit), chunked writes, signal handling.
Standard library only."""

import os
import signal
import time
import tty


class PtyDevice:
    """A pty pair whose slave side a driver opens like a serial port.

    symlink:   a symbolic link to the slave (e.g. /tmp/x/aurora -> /dev/pts/7), created atomically,
               the way udev names a real adapter (/dev/serial/by-id/...). A driver that reopens
               this path after an "unplug" finds the replacement emulator's pty.
    link_file: a text file holding the slave path (written atomically).
    Both are removed on close() if they still point at this emulator's slave."""

    def __init__(self, symlink=None, link_file=None):
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)  # no echo, no CR/NL translation until the driver configures the port
        self.path = os.ttyname(self.slave)
        self.symlink = symlink
        self.link_file = link_file
        if symlink:
            d = os.path.dirname(os.path.abspath(symlink))
            os.makedirs(d, exist_ok=True)
            tmp = "%s.tmp.%d" % (symlink, os.getpid())
            try:
                os.unlink(tmp)
            except OSError:
                pass
            os.symlink(self.path, tmp)
            os.replace(tmp, symlink)
        if link_file:
            tmp = "%s.tmp.%d" % (link_file, os.getpid())
            with open(tmp, "w") as f:
                f.write(self.path + "\n")
            os.replace(tmp, link_file)

    def close(self):
        if self.symlink:
            try:
                if os.readlink(self.symlink) == self.path:
                    os.unlink(self.symlink)
            except OSError:
                pass
        if self.link_file:
            try:
                with open(self.link_file) as f:
                    if f.read().strip() == self.path:
                        os.unlink(self.link_file)
            except OSError:
                pass
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:
                pass


def write_all(fd, data, chunk=0, delay=0.0):
    """Writes all bytes; with chunk > 0 in pieces of `chunk` bytes, `delay` seconds apart (so that a
    reader sees partial frames / lines)."""
    view = memoryview(data)
    step = chunk if chunk > 0 else len(view)
    first = True
    while view:
        if not first and delay > 0:
            time.sleep(delay)
        first = False
        piece = view[:step]
        while piece:
            n = os.write(fd, piece)
            piece = piece[n:]
        view = view[step:]


def exit_on_signals():
    """SIGTERM / SIGINT end the emulator through SystemExit, so finally-blocks clean up."""

    def on_signal(signum, frame):
        raise SystemExit(0)

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)


def exit_with_parent():
    """Makes the kernel send SIGTERM to this emulator when the process that started it dies
    (prctl PR_SET_PDEATHSIG), so that a test killed by a time-out leaves no emulator behind."""
    import ctypes
    parent = os.getppid()
    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)  # 1 = PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass
    if os.getppid() != parent or parent == 1:  # the parent died before prctl took effect
        raise SystemExit(0)


def write_atomic(path, text):
    tmp = "%s.tmp.%d" % (path, os.getpid())
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, path)
