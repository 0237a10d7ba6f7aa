"""SUNDIALS' own error lines: kept off the terminal and put into regmech's errors.

When IDA fails (too many steps in an output interval, repeated error-test or convergence failures, a
bad input), SUNDIALS reports it through the error handlers of its context. scikit-sundae installs a
handler that prints ``[IDASolve, Error: -1] At t = ..., mxstep steps taken before reaching tout.``
with Python's ``print`` (to ``sys.stdout``); SUNDIALS' default handler, which the native path
(``ida_native``) would keep, writes it to the process's stderr. regmech raises a ``SimulationError``
for the same failure, so the line is noise on a terminal, a stray cell output in a notebook and, in a
study of thousands of runs, thousands of lines; its text (the time and SUNDIALS' reason) belongs in
the error instead.

``kept()`` is a context manager around a solve: the SUNDIALS lines written by the current thread
while it is open are collected in the list it yields, and nothing else changes.

* scikit-sundae path: ``sys.stdout`` is replaced, while at least one thread is inside ``kept()``, by
  a router that passes every write through to the stream it replaced, except a write of the calling
  thread that has the form of scikit-sundae's message (``[<function>, Error: <code>] <text>``; the
  newline ``print`` writes after it is dropped too). Other output of the solving thread (a user's
  ``print`` inside a signal callable) and every write of other threads go through unchanged and at
  once. Which thread is solving is thread-local state, so thread-pool sweeps keep each run's lines
  apart; the router is installed when the first thread enters and removed when the last one leaves
  (if nothing replaced ``sys.stdout`` in between). The router and every stream it wrote to stay alive
  for the life of the process (``_streams``: a thread may still be inside ``print`` with a borrowed
  reference to them). Cost: a lock and two attribute swaps per solve, microseconds.
* native path: its SUNDIALS context gets ``handler()`` as its only error handler (a ctypes
  callback, called only when IDA reports an error), which hands the message to the same list.
"""

from __future__ import annotations

import ctypes
import os
import re
import sys
import threading

# SUNDIALS' warnings do not go through the error handlers but through its logger, which writes them to the
# process's standard output (``[WARNING][rank 0][.../ida.c:1470][IDASolve] At the end of the first step, there are still
# some root functions identically 0``: a friction guard that is exactly zero at a segment's start, which regmech's
# event logic expects and handles, ``hybrid.events``). The logger reads this variable when a solver's context is
# created; empty, it writes nothing. A user who set it keeps their choice.
os.environ.setdefault("SUNLOGGER_WARNING_FILENAME", "")

#: scikit-sundae's error line (its ``_sunerr_handler``): ``\n[IDASolve, Error: -1] <message>\n``
_LINE = re.compile(r"\A\s*\[(\w+), Error: (-?\d+)\]\s*(.*?)\s*\Z", re.S)

_local = threading.local()
_lock = threading.Lock()
_inside = 0             # threads inside ``kept()``
_router = None          # the one ``_Router``: installed as sys.stdout while _inside > 0, never released
#: every stream the router has passed writes to, kept alive for the life of the process (a handful: the
#: terminal's, pytest's, a notebook's). CPython 3.11's ``print`` holds only a borrowed reference to
#: ``sys.stdout`` while it writes; a router (or a stream) released while another thread is inside such a
#: ``print`` is freed under it: four failing solves in threads and a fifth thread printing crashed the
#: interpreter (segmentation fault) in 3 of 3 runs when the router was dropped at the last exit
_streams: dict = {}


class _Router:
    """``sys.stdout`` while a solve runs: SUNDIALS lines of a solving thread go to its list, the rest on."""

    def __init__(self, stream):
        self._stream = stream

    def write(self, text):
        box = getattr(_local, "box", None)
        if box is not None and isinstance(text, str):
            found = _LINE.match(text)
            if found:
                box.append(f"[{found.group(1)}, error {found.group(2)}] {' '.join(found.group(3).split())}")
                _local.newline_owed = True
                return len(text)
            if text == "\n" and getattr(_local, "newline_owed", False):
                _local.newline_owed = False      # the end of the print() that wrote the line
                return len(text)
            _local.newline_owed = False
        return self._stream.write(text)

    def __getattr__(self, name):            # flush, fileno, encoding, isatty, ...: the stream's own
        return getattr(self._stream, name)


class kept:
    """``with kept() as lines:``: collect the SUNDIALS error lines the current thread's solve writes."""

    __slots__ = ("box", "outer")

    def __enter__(self):
        global _inside, _router
        with _lock:
            if _inside == 0:
                stream = sys.stdout
                if stream is not _router:
                    _streams.setdefault(id(stream), stream)
                    if _router is None:
                        _router = _Router(stream)
                    else:
                        _router._stream = stream
                    sys.stdout = _router
            _inside += 1
        self.box: list[str] = []
        self.outer = getattr(_local, "box", None)
        _local.box = self.box
        return self.box

    def __exit__(self, *exc):
        global _inside, _router
        _local.box = self.outer
        if self.outer is not None:
            self.outer.extend(self.box)
        with _lock:
            _inside -= 1
            if _inside == 0 and sys.stdout is _router:      # else someone replaced it meanwhile: leave theirs
                sys.stdout = _router._stream     # the router object itself stays (see ``_streams``)
        return False


def said(lines) -> str:
    """The text to append to an error message: `` SUNDIALS said: ...`` (empty without lines)."""
    lines = list(dict.fromkeys(lines))         # one copy of a repeated line, in order
    return f" SUNDIALS said: {' '.join(lines)}" if lines else ""


#: ``SUNErrHandlerFn``: (line, function, file, message, error code, user data, context)
HANDLER_TYPE = ctypes.CFUNCTYPE(None, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p, ctypes.c_char_p,
                                ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p)


def _native_handler(line, func, file, msg, code, user_data, ctx):
    """Error handler of the native path's SUNDIALS contexts: the message goes to the solving thread's list
    (``kept``); outside ``kept()`` it is dropped, since every native solve runs inside it."""
    box = getattr(_local, "box", None)
    if box is not None:
        name = (func or b"").decode("utf-8", "replace")
        text = " ".join((msg or b"").decode("utf-8", "replace").split())
        box.append(f"[{name}, error {code}] {text}")


#: the one ctypes callback object (it must outlive every context it is installed in: module lifetime)
handler = HANDLER_TYPE(_native_handler)
