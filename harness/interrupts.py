"""Ctrl-C and SIGTERM on the command line: the first one interrupts (a KeyboardInterrupt, which the
command line turns into exit code 130 with the rows so far kept), later ones are ignored, so that the
clean-up the first one started runs to its end.

Python runs a signal handler in the main thread between two bytecodes, wherever that thread is. In
three kinds of places the KeyboardInterrupt must not be raised, so the handler keeps it and raises it
as soon as the main thread has left them:

* a function that C calls back (`called_from_c`: an FMU's logger, the counting memory functions):
  ctypes would print the exception, swallow it and hand the FMU an undefined return value (a memory
  block at a random address: heap corruption), and the interrupt would be lost, the run going on to
  its end while further Ctrl-C are ignored;
* an import: a module left half executed, or the exception turned into another (numpy's extension
  module reports an ImportError);
* a section marked `held()`: where something is taken or given back that must not be lost half way
  (an FMU instance and its states, an extracted FMU, the rename of an output file); the section's
  end raises what it kept.

From a callback or an import the kept signal is sent again a moment later (a real signal to the main
thread, so that a wait in a system call ends too), until the main thread is where it may be raised.
A section holds interrupts only in the main thread, the one the handler runs in.
"""
from __future__ import annotations

import _thread
import signal
import sys
import time

SIGNALS = (signal.SIGINT, signal.SIGTERM)
RESEND_SECONDS = 0.005  # a kept signal comes again after this long (callbacks and imports end sooner)

_IMPORT_MODULES = ("importlib._bootstrap", "importlib._bootstrap_external")
_called_from_c: set = set()


class _State:
    previous: dict | None = None  # the handlers before `install`, while installed
    main: int | None = None  # the thread the handler runs in (the main thread), while installed
    stopping = False  # the first signal was raised: the ones after it are ignored
    pending: int | None = None  # a signal kept until the main thread may raise it
    resending = False  # a thread is about to send the kept signal again
    depth = 0  # held sections open in the main thread


_state = _State()


def called_from_c(function):
    """Marks a function that C calls (through a ctypes callback): no interrupt is raised inside it."""
    _called_from_c.add(function.__code__)
    return function


def _unsafe(frame) -> bool:
    """Whether the frame, or one that called it, is a callback from C or an import."""
    while frame is not None:
        if frame.f_code in _called_from_c or frame.f_globals.get("__name__") in _IMPORT_MODULES:
            return True
        frame = frame.f_back
    return False


def _handler(signum, frame) -> None:
    state = _state
    if state.stopping:
        return
    if state.depth or _unsafe(frame):
        if state.pending is None:
            state.pending = signum
        if not state.depth:
            _resend_later()
        return
    state.pending = None
    state.stopping = True
    raise KeyboardInterrupt


def _resend_later() -> None:
    state = _state
    if state.resending:
        return
    state.resending = True

    def resend() -> None:
        time.sleep(RESEND_SECONDS)
        state.resending = False
        signum = state.pending
        main = state.main
        if signum is not None and main is not None and not state.stopping and signal.getsignal(signum) is _handler:
            signal.pthread_kill(main, signum)
    # the low-level thread: threading's own locks may be held by the code the signal interrupted
    _thread.start_new_thread(resend, ())


class held:
    """A section that interrupts do not cut short: a signal that comes inside it is raised when the
    outermost section ends (in the main thread; elsewhere it changes nothing)."""

    __slots__ = ()

    def __enter__(self) -> None:
        if _thread.get_ident() == _state.main:
            _state.depth += 1

    def __exit__(self, *exc) -> None:
        if _thread.get_ident() == _state.main:
            _state.depth -= 1
            if not _state.depth and _state.pending is not None:
                _handler(_state.pending, sys._getframe(1))


def install() -> bool:
    """The handler for SIGINT and SIGTERM, in the main thread (a SIGINT that whoever started the
    process ignores, as a shell does for a background job, stays ignored). False where it was already
    installed or cannot be (another thread): then `uninstall` is not to be called."""
    if _state.previous is not None:
        return False
    previous = {}
    try:
        for signum in SIGNALS:
            if signum == signal.SIGINT and signal.getsignal(signum) is signal.SIG_IGN:
                continue
            previous[signum] = signal.signal(signum, _handler)
    except ValueError:  # not the main thread: signals are the main thread's
        return False
    _state.stopping, _state.pending, _state.depth = False, None, 0
    _state.previous, _state.main = previous, _thread.get_ident()
    return True


def uninstall() -> None:
    """The handlers that were there before `install`."""
    previous, _state.previous, _state.main = _state.previous or {}, None, None
    for signum, handler in previous.items():
        signal.signal(signum, handler)
    _state.stopping, _state.pending, _state.depth = False, None, 0
