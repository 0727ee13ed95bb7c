"""The browser tests' harness (issue 56): one headless chromium per set of flags per test process,
driven over its DevTools protocol, instead of one chromium per page opened; and ``hbrdf`` run in
the test's own process where a test is about the page, not the command's process.

Why (measured on 2 loaded cores, 2026-11-28): a page opened by ``chromium --dump-dom`` took 7-9 s,
of which about 3 s was chromium starting (a trivial page: 2-3 s) and the rest the page's own load
(parsing its 2 MiB of inlined data, SwiftShader compiling its shader, drawing); in one browser a
second page with the same shader loads in 1-5 s (no start, and the GPU process keeps the compiled
program). ``hbrdf view`` as a subprocess took 5-8 s, of which importing torch was 3-4 s; in the
test's process (torch already imported) 0.5 s.

Each page gets a tab of its own (a new target), closed after it is read: no state of one page
(its WebGL2 context, its console) reaches the next. Except where a test asks to ``keep`` it
(:func:`open_url`, :class:`Tab`): the pages several tests read (a model's page in test_view and
test_view_webgpu, the uniform and four-layer pages of test_view_svbrdf, the sources page) stay open in
a tab per page bytes and backend, and the next fragment is drawn there by changing ``location.hash``:
the page redraws without loading again (docs/VIEWER.md, "URL parameters"), so SwiftShader compiles
its shaders once per tab instead of once per picture (2-6 s of CPU each); the console lines read
then are those since the change. test_view's test_fragment_change_draws_what_a_fresh_load_draws
holds such a change to what a fresh load of the new URL shows, pixel for pixel. What a page reports is as ``--dump-dom`` and
chromium's log gave it: the document once the window's load event has fired and the page's title
says "hbrdf view: ..." (ok or an error; WebGPU draws after the load event), and every console
message of that tab (the console API, uncaught exceptions and the browser's own messages: the
Runtime and Log domains' events) as a line with ``:CONSOLE``, as chromium's log writes them.
After the title the page draws the one animation frame it has asked for, if any (its frame loop runs
as a user's page's does; a readback page has drawn all its samples before its title) and no more
(a page without readback refines its 320 x 320 picture frame after frame, seconds a frame on
SwiftShader, and nothing reads them: ``--dump-dom`` drew them for its 20 s virtual-time budget);
then messages the GPU process sends about the work so far (a driver's error, a performance note)
are waited for: the page's WebGPU queues done, one synchronous call on each of its WebGL2 contexts
(a round trip through the GPU process), one task turn.
"""

from __future__ import annotations

import atexit
import ctypes
import hashlib
import json
import os
import pickle
import select
import shutil
import signal
import subprocess
import tempfile
import time
import urllib.parse

#: JavaScript run in every page before its own scripts. It keeps the WebGL2 contexts and WebGPU
#: devices the page makes (the page's calls pass through unchanged) and counts its animation
#: frames; window.__hbrdfSettle() (called once the title is set) lets the page draw the one frame
#: it has asked for, if any (its frame loop runs once, as a user's page does), holds the frames it
#: asks for after that (a page without readback refines its picture frame after frame, each a draw
#: of the 320 x 320 canvas on SwiftShader, seconds each, which nothing reads), then settles the GPU
#: work: the WebGPU queues done, one synchronous call on each WebGL2 context (a round trip through
#: the GPU process: its messages about the work so far come first), one task turn (the console
#: messages those posted are added).
_KEEP_CONTEXTS = """(function () {
  const contexts = [], devices = [];
  const getContext = HTMLCanvasElement.prototype.getContext;
  HTMLCanvasElement.prototype.getContext = function () {
    const c = getContext.apply(this, arguments);
    if (c && typeof WebGL2RenderingContext !== "undefined" && c instanceof WebGL2RenderingContext && contexts.indexOf(c) < 0) contexts.push(c);
    return c;
  };
  if (typeof GPUAdapter !== "undefined") {
    const requestDevice = GPUAdapter.prototype.requestDevice;
    GPUAdapter.prototype.requestDevice = function () {
      return requestDevice.apply(this, arguments).then(function (d) { devices.push(d); return d; });
    };
  }
  let asked = 0, hold = false, afterFrame = null, held = [];
  const raf = window.requestAnimationFrame.bind(window);
  window.requestAnimationFrame = function (callback) {
    if (hold) { held.push(callback); return 0; }
    asked++;
    return raf(function (t) {
      asked--;
      if (hold) { held.push(callback); return; }
      try { callback(t); } finally {
        if (afterFrame) { const f = afterFrame; afterFrame = null; hold = true; f(); }
      }
    });
  };
  function gpuSettled() {
    return Promise.all(devices.map(function (d) { return d.queue.onSubmittedWorkDone().catch(function () {}); }))
      .then(function () {
        contexts.forEach(function (gl) { gl.getError(); });
        return new Promise(function (resolve) {
          const channel = new MessageChannel();
          channel.port1.onmessage = function () { resolve(); };
          channel.port2.postMessage(0);
        });
      });
  }
  Object.defineProperty(window, "__hbrdfSettle", { value: function () {
    return new Promise(function (resolve) { if (asked > 0) afterFrame = resolve; else { hold = true; resolve(); } })
      .then(gpuSettled);
  } });
  // Before a change of the fragment (Tab.goto): the frames the page asked for while held are asked
  // for again, so that its frame loop runs as a user's page's does until the next __hbrdfSettle.
  Object.defineProperty(window, "__hbrdfRelease", { value: function () {
    hold = false;
    afterFrame = null;
    const callbacks = held;
    held = [];
    callbacks.forEach(function (c) { window.requestAnimationFrame(c); });
  } });
})();"""

#: JavaScript: a promise of the title once it says "hbrdf view: ..." (a MutationObserver: the page's
#: own event, no polling) and the page settled (_KEEP_CONTEXTS), or of whatever it says after the
#: deadline.
_WAIT_FOR_TITLE = """new Promise(function (resolve) {
  function done() { return document.title.startsWith('hbrdf view:'); }
  function settle() { window.__hbrdfSettle().then(function () { resolve(document.title); }); }
  if (done()) return settle();
  const observer = new MutationObserver(function () { if (done()) { observer.disconnect(); settle(); } });
  observer.observe(document, {subtree: true, childList: true, characterData: true});
  setTimeout(function () { observer.disconnect(); resolve(document.title); }, %d);  // the deadline
})"""


#: JavaScript (Tab.goto): the page's frames released (_KEEP_CONTEXTS), its title reset to "hbrdf view"
#: (the page titles it again once the new fragment's picture is drawn: _WAIT_FOR_TITLE then waits for
#: that, not for the previous title), a mark that a reload would drop, then the new fragment.
_CHANGE_FRAGMENT = """window.__hbrdfRelease(); document.title = 'hbrdf view';
Object.defineProperty(window, '__hbrdfSameDocument', { value: true, configurable: true });
location.hash = %s; location.hash"""


class Reloaded(RuntimeError):
    """The page loaded itself again on a change of its fragment (viewer.js does for another backend=,
    or after an error that was not the fragment's): what it shows is a fresh load's, not a change's."""


def _die_with_parent():
    """In the child before exec: SIGTERM when the test process dies (a killed xdist worker leaves
    no browser behind)."""
    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


class Browser:
    """Chromium with ``flags`` and a profile of its own, driven over --remote-debugging-pipe
    (requests on its fd 3, answers and events on its fd 4, JSON ended by a NUL byte)."""

    def __init__(self, exe, flags):
        self.flags = list(flags)
        self.profile = tempfile.mkdtemp(prefix="hbrdf-chromium-")
        self.stderr = tempfile.TemporaryFile()
        to_r, self.to_w = os.pipe()
        self.from_r, from_w = os.pipe()

        def child():  # chromium reads fd 3 and writes fd 4 (copies first: the pipes may hold 3 or 4)
            a, b = os.dup(to_r), os.dup(from_w)
            os.dup2(a, 3)
            os.dup2(b, 4)
            _die_with_parent()

        self.proc = subprocess.Popen([exe, *self.flags, f"--user-data-dir={self.profile}", "--remote-debugging-pipe",
                                      "about:blank"], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                     stderr=self.stderr, preexec_fn=child, close_fds=False)
        os.close(to_r)
        os.close(from_w)
        self.buf = b""
        self.next_id = 0
        self.events = []
        self.sessions = set()  # the open tabs' DevTools sessions

    def alive(self):
        return self.proc.poll() is None

    def _pump(self, deadline, what):
        """Reads what chromium has sent, waiting until ``deadline`` for something."""
        left = deadline - time.monotonic()
        if left <= 0 or not select.select([self.from_r], [], [], left)[0]:
            raise TimeoutError(f"DevTools {what}: no answer in time")
        chunk = os.read(self.from_r, 1 << 20)
        if not chunk:
            raise RuntimeError(f"DevTools {what}: chromium closed the pipe (exit {self.proc.poll()})")
        self.buf += chunk
        while b"\0" in self.buf:
            raw, self.buf = self.buf.split(b"\0", 1)
            m = json.loads(raw)
            if "id" in m or m.get("sessionId") in self.sessions:  # answers, and events of open tabs
                self.events.append(m)

    def call(self, method, params=None, session=None, timeout=60.0):
        self.next_id += 1
        want = self.next_id
        msg = {"id": want, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        os.write(self.to_w, json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while True:
            for i, m in enumerate(self.events):
                if m.get("id") == want:
                    del self.events[i]
                    if "error" in m:
                        raise RuntimeError(f"DevTools {method}: {m['error']}")
                    return m["result"]
            self._pump(deadline, method)

    def wait_event(self, method, session, timeout):
        deadline = time.monotonic() + timeout
        while True:
            for i, m in enumerate(self.events):
                if m.get("method") == method and m.get("sessionId") == session:
                    return self.events.pop(i)
            self._pump(deadline, method)

    def take_events(self, session):
        mine = [m for m in self.events if m.get("sessionId") == session and "method" in m]
        self.events = [m for m in self.events if not (m.get("sessionId") == session and "method" in m)]
        return mine

    def open(self, url, timeout):
        """(title, dom, console lines) of ``url`` in a new tab, read as the module docstring says; the
        tab is closed after."""
        tab = Tab(self, url, timeout)
        tab.close()
        return tab.first

    def read(self, session, deadline):
        """(title, dom, console lines) of the tab once its title says "hbrdf view: ..." and it has
        settled (or at ``deadline``); the console lines are those since the last read."""
        left_ms = max(1, int((deadline - time.monotonic()) * 1000))
        self.call("Runtime.evaluate", {"expression": _WAIT_FOR_TITLE % left_ms, "awaitPromise": True,
                                       "returnByValue": True}, session, timeout=left_ms / 1000 + 30)
        r = self.call("Runtime.evaluate", {"expression": "[document.title, document.documentElement.outerHTML]",
                                           "returnByValue": True}, session)
        title, dom = r["result"]["value"]
        console = [_console_line(m) for m in self.take_events(session)]
        return title, dom, [c for c in console if c is not None]

    def close(self):
        try:
            self.call("Browser.close", timeout=10)
        except Exception:
            pass
        try:
            self.proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            self.proc.kill()  # our own chromium, by its handle
            self.proc.wait()
        for fd in (self.to_w, self.from_r):
            os.close(fd)
        self.stderr.close()
        shutil.rmtree(self.profile, ignore_errors=True)


class Tab:
    """A page in a tab of its own: opened by a fresh load of ``url`` (its first read: ``first``), then
    kept open for :meth:`goto`, which changes the page's fragment in it: the page draws the new
    fragment's picture without loading again (viewer.js, docs/VIEWER.md "URL parameters"), so the
    shaders SwiftShader compiled for the first load serve every later picture. Reads are as the module
    docstring says; a change's console lines are those since the change."""

    def __init__(self, browser, url, timeout):
        self.browser = browser
        self.hash = url.partition("#")[2]
        self.target = browser.call("Target.createTarget", {"url": "about:blank"})["targetId"]
        self.session = None
        try:
            self.session = browser.call("Target.attachToTarget", {"targetId": self.target, "flatten": True})["sessionId"]
            browser.sessions.add(self.session)
            for domain in ("Page", "Runtime", "Log"):
                browser.call(f"{domain}.enable", session=self.session)
            browser.call("Page.addScriptToEvaluateOnNewDocument", {"source": _KEEP_CONTEXTS}, self.session)
            browser.take_events(self.session)  # about:blank's
            deadline = time.monotonic() + timeout
            nav = browser.call("Page.navigate", {"url": url}, self.session)
            assert "errorText" not in nav, nav
            browser.wait_event("Page.loadEventFired", self.session, timeout)
            self.first = browser.read(self.session, deadline)
        except BaseException:
            self.close()
            raise

    def goto(self, hash_, timeout):
        """(title, dom, console lines since the change) of the page after its fragment is changed to
        ``hash_`` in this tab, read once its title says "hbrdf view: ..." again. Raises
        :class:`Reloaded` when the page loaded itself again instead."""
        if hash_ == self.hash:
            raise ValueError(f"the tab shows #{hash_} already: no change of the fragment")
        b = self.browser
        b.call("Page.bringToFront", session=self.session)  # a tab in the background draws no frames
        b.take_events(self.session)  # the previous picture's (read already)
        deadline = time.monotonic() + timeout
        b.call("Runtime.evaluate", {"expression": _CHANGE_FRAGMENT % json.dumps("#" + hash_), "returnByValue": True},
               self.session)
        self.hash = hash_
        try:
            got = b.read(self.session, deadline)
            same = b.call("Runtime.evaluate", {"expression": "window.__hbrdfSameDocument === true",
                                               "returnByValue": True}, self.session)["result"]["value"]
        except RuntimeError as e:
            if "context" in str(e).lower() or "navigat" in str(e).lower():
                raise Reloaded(f"#{hash_}: the page loaded again ({e})") from e
            raise
        if not same:
            raise Reloaded(f"#{hash_}: the page loaded again")
        return got

    def close(self):
        b = self.browser
        try:
            b.call("Target.closeTarget", {"targetId": self.target}, timeout=30)
        except (RuntimeError, TimeoutError):
            pass
        b.sessions.discard(self.session)
        b.events = [m for m in b.events if m.get("sessionId") != self.session or "id" in m]  # its late events


def _console_line(event):
    """A console event as chromium's log line (``...:CONSOLE(line)] "text", source: url (line)``);
    None for the events that are no console message."""
    method, p = event["method"], event["params"]
    if method == "Runtime.consoleAPICalled":
        text = " ".join(str(a.get("value", a.get("description", a.get("type")))) for a in p.get("args", []))
        frame = (p.get("stackTrace") or {}).get("callFrames", [{}])[:1] or [{}]
        url, line = frame[0].get("url", ""), frame[0].get("lineNumber", -1) + 1
        return f"[{p.get('type', 'log')}:CONSOLE({line})] \"{text}\", source: {url} ({line})"
    if method == "Runtime.exceptionThrown":
        d = p["exceptionDetails"]
        text = (d.get("exception") or {}).get("description") or d.get("text", "")
        return f"[exception:CONSOLE({d.get('lineNumber', -1) + 1})] \"{text}\", source: {d.get('url', '')}"
    if method == "Log.entryAdded":
        e = p["entry"]
        return f"[{e.get('level')}:{e.get('source')}:CONSOLE({e.get('lineNumber', 0)})] \"{e.get('text')}\", " \
               f"source: {e.get('url', '')}"
    return None


_BROWSERS: dict = {}


def browser(exe, flags) -> Browser:
    """This process's chromium with ``flags`` (started at the first call; again if it died)."""
    key = (exe, tuple(flags))
    b = _BROWSERS.get(key)
    if b is None or not b.alive():
        b = _BROWSERS[key] = Browser(exe, flags)
    return b


@atexit.register
def _close_all():
    _KEPT.clear()  # their browsers close them
    for b in list(_BROWSERS.values()):
        b.close()
    _BROWSERS.clear()


def page_url(page, hash_=""):
    return "file://" + urllib.parse.quote(os.path.abspath(page)) + ("#" + hash_ if hash_ else "")


def open_url(exe, flags, page, hash_="", timeout=180.0, keep=False):
    """(title, dom, console lines) of the page file ``page`` with URL fragment ``hash_``: a fresh load in
    a new tab, closed after; with ``keep``, in this process's kept tab of these page bytes and
    backend (:func:`_in_kept_tab`): there a change of the fragment where the tab is open already."""
    b = browser(exe, flags)
    try:
        if keep:
            return _in_kept_tab(b, exe, flags, page, hash_, timeout)
        return b.open(page_url(page, hash_), timeout)
    except (RuntimeError, TimeoutError):
        if b.alive():
            raise
        raise RuntimeError("chromium died: " + _tail(b))


#: Pages kept open for open_url(keep=True), per browser, least recently used first; at most
#: MAX_KEPT_TABS (each holds its WebGL2 context or WebGPU device, and chromium loses the oldest
#: WebGL2 context past 16).
_KEPT: dict = {}
MAX_KEPT_TABS = 8


def _kept_key(exe, flags, page, hash_):
    backend = urllib.parse.parse_qs(hash_).get("backend")
    return (exe, tuple(flags), os.path.abspath(page), file_sha256(page), backend[-1] if backend else None)


def _in_kept_tab(b, exe, flags, page, hash_, timeout):
    """open_url(keep=True): the kept tab of (the page's path and bytes, its backend= parameter,
    chromium and its flags) driven to ``hash_``; a new one (a fresh load) when there is none, when
    it shows ``hash_`` already, or when the page loaded itself again (view_harness.Reloaded)."""
    key = _kept_key(exe, flags, page, hash_)
    tab = _KEPT.pop(key, None)
    if tab is not None and (tab.browser is not b or not b.alive()):
        tab = None
    got = None
    if tab is not None and tab.hash != hash_:
        try:
            got = tab.goto(hash_, timeout)
        except Reloaded:
            got = None
        except BaseException:
            tab.close()
            raise
    if got is None:
        if tab is not None:
            tab.close()
        tab = Tab(b, page_url(page, hash_), timeout)
        got = tab.first
    _KEPT[key] = tab
    for old in [k for k in _KEPT if _KEPT[k].browser is b][:-MAX_KEPT_TABS]:
        _KEPT.pop(old).close()
    return got


def close_kept(page):
    """Closes every kept tab of ``page`` (a test that saw its context lost opens it fresh)."""
    for k in [k for k in _KEPT if k[2] == os.path.abspath(page)]:
        _KEPT.pop(k).close()


def _tail(b):
    b.stderr.seek(0)
    return b.stderr.read().decode("utf-8", "replace")[-3000:]


def cli(*args):
    """``hbrdf ARGS`` in this process (the same ``hybridbrdf.cli.main`` as the command; torch is
    imported once): :func:`helpers.run_cli_here`, as helpers.run_cli reports it."""
    from helpers import run_cli_here

    return run_cli_here(*args)


# ---- pictures several tests read ----

_MADE: dict = {}  # key -> value, this process's


def shared(tmp_path_factory, what, key_parts, make):
    """``make()``'s value (a page's picture, a tracer's render), made once per test run for every test
    that asks with the same ``key_parts``, which must name everything the value depends on (file
    contents by their sha256, the fragment, the flags, the seed). Within a process it is kept in
    memory; under pytest-xdist the first worker to ask makes it and writes it into the folder the
    run's workers share (:func:`helpers.run_shared_path`: fresh for every run, so nothing of an
    earlier run is read) and the other reads it. Why: a page load is mostly SwiftShader compiling
    the page's shader (2-6 s of CPU, redone in every tab), and the tests compare some pictures and
    tracer renders that another test has made already. Nothing is written when ``make`` fails (its
    assertion fails the test that asked; the next one to ask makes it again)."""
    key = hashlib.sha256(json.dumps([what, key_parts], sort_keys=True, default=str).encode()).hexdigest()[:32]
    if key in _MADE:
        return _MADE[key]
    if "PYTEST_XDIST_WORKER" not in os.environ:
        value = make()
    else:
        from helpers import run_shared_path

        with run_shared_path(tmp_path_factory, f"view-{what}-{key}.pickle") as path:
            if path.exists():
                value = pickle.loads(path.read_bytes())
            else:
                value = make()
                part = path.with_name(path.name + ".part")
                part.write_bytes(pickle.dumps(value))
                os.replace(part, path)
    _MADE[key] = value
    return value


def file_sha256(path) -> str:
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def content_key(value):
    """``value`` (a scene dict) with every string that names an existing file or folder followed by the
    sha256 of its bytes (a folder: of each file's name and bytes): a key that changes when a file the
    value reads changes, not only when its path does."""
    if isinstance(value, dict):
        return {k: content_key(v) for k, v in sorted(value.items())}
    if isinstance(value, list):
        return [content_key(v) for v in value]
    if isinstance(value, str) and value and os.path.isfile(value):
        return [value, file_sha256(value)]
    if isinstance(value, str) and value and os.path.isdir(value):
        h = hashlib.sha256()
        for root, _, files in sorted(os.walk(value)):
            for name in sorted(files):
                h.update(os.path.relpath(os.path.join(root, name), value).encode() + b"\0")
                h.update(file_sha256(os.path.join(root, name)).encode())
        return [value, h.hexdigest()]
    return value
