"""What a browser test leaves behind when it fails: a Playwright trace of every browser context it opened
(``test-artifacts/traces/NAME.zip``: the pages' DOM snapshots before and after each action, network and console, to
open with ``playwright show-trace``), a screenshot of each page still open when it failed (``NAME-pageN.png``: the
views' canvases, which a DOM snapshot does not hold), and the pages' console errors, uncaught errors and failed
requests in the failure's report.

Every context the test makes through its ``browser`` fixture (:class:`RecordedBrowser`) records from its start; the
trace is written only when the test failed (a context closed by the test itself before its outcome is known writes
it to a temporary file, kept or removed at the end). ``tests/conftest.py`` wires it: the ``browser`` fixture, and a
report hook that adds the ``browser`` section to a failure."""
from __future__ import annotations

import re
import shutil
import tempfile
from pathlib import Path
from typing import Any

import pytest

#: Where the traces of failed tests go (gitignored with the rest of ``test-artifacts``).
TRACES = Path(__file__).resolve().parents[1] / "test-artifacts" / "traces"
#: How many lines of the pages' console and requests a failure's report keeps (the last ones).
REPORT_LINES = 60


class Recorder:
    """One test's record: its contexts' traces and the lines its pages said (console errors, failed requests)."""

    def __init__(self, nodeid: str) -> None:
        self.name = re.sub(r"[^\w.-]+", "_", nodeid.removeprefix("tests/")).strip("_")[:150]
        self.lines: list[str] = []
        #: None while the test runs, then whether it failed (set by the report hook)
        self.failed: bool | None = None
        self.contexts: list[RecordedContext] = []
        self.pending: dict[int, Path] = {}  # context index -> its trace, written before the outcome was known
        self._scratch: Path | None = None

    def trace_path(self, index: int) -> Path:
        return TRACES / (f"{self.name}.zip" if index == 0 else f"{self.name}-{index + 1}.zip")

    def shot_path(self, context: int, page: int) -> Path:
        """Where the screenshot of page ``page`` of context ``context`` goes when the test failed."""
        return TRACES / f"{self.trace_path(context).stem}-page{page + 1}.png"

    def scratch(self) -> Path:
        if self._scratch is None:
            self._scratch = Path(tempfile.mkdtemp(prefix="v3d-trace-"))
        return self._scratch

    def note(self, line: str) -> None:
        self.lines.append(line)

    def report(self, traces: bool = True) -> str:
        """The failure's ``browser`` section: where the traces are (``traces``: they are kept), then what the pages
        said."""
        shown = self.lines[-REPORT_LINES:]
        head = [f"trace{'s' if len(self.contexts) > 1 else ''}: "
                + ", ".join(str(self.trace_path(i).relative_to(TRACES.parents[1])) for i in range(len(self.contexts)))
                + " (playwright show-trace FILE), beside each a screenshot of every page it left open (-pageN.png)"]\
            if self.contexts and traces else []
        if len(self.lines) > len(shown):
            head.append(f"... {len(self.lines) - len(shown)} earlier lines left out")
        return "\n".join(head + (shown or ["the pages logged no console error and no failed request"]))

    def finish(self) -> None:
        """At the test's end: close what is still open (writing its trace when the test failed), keep the traces
        written earlier when it failed, remove the rest."""
        for context in list(self.contexts):
            if not context.closed:
                context.close()
        for index, written in self.pending.items():
            if self.failed:
                TRACES.mkdir(parents=True, exist_ok=True)
                shutil.move(str(written), self.trace_path(index))
        if self._scratch is not None:
            shutil.rmtree(self._scratch, ignore_errors=True)


class RecordedContext:
    """A Playwright ``BrowserContext`` that records a trace from its start and notes what its pages say; every
    other attribute is the context's own."""

    def __init__(self, context: Any, recorder: Recorder) -> None:
        self._context = context
        self._recorder = recorder
        self._index = len(recorder.contexts)
        self.closed = False
        recorder.contexts.append(self)
        # DOM snapshots, not the screencast: the screencast's frames cost a browser test about a tenth of its CPU
        # (three modules run in turn with and without it, benchmarks/TEST_LOOP.md); a failure's last state is
        # kept by a screenshot of each page still open instead (:meth:`close`)
        context.tracing.start(screenshots=False, snapshots=True)
        context.on("page", self._watch)

    def _watch(self, page: Any) -> None:
        note = self._recorder.note
        page.on("console", lambda m: note(f"console {m.type}: {m.text}") if m.type in ("error", "warning") else None)
        page.on("pageerror", lambda exc: note(f"uncaught error: {exc}"))
        page.on("requestfailed", lambda r: note(f"request failed: {r.method} {r.url} ({r.failure})"))
        page.on("response", lambda r: note(f"answered {r.status}: {r.request.method} {r.url}") if r.status >= 400
                else None)

    def _screenshots(self) -> None:
        """A failed test's last sight of each page still open (the canvases a DOM snapshot does not hold)."""
        for number, page in enumerate(self._context.pages):
            try:
                page.screenshot(path=str(self._recorder.shot_path(self._index, number)), timeout=10_000)
            except Exception as exc:  # a page that crashed or hung: its trace is still written
                self._recorder.note(f"no screenshot of page {number + 1}: {exc}")

    def close(self, **kwargs: Any) -> None:
        """Stop the trace (written where the test's outcome says), then close the context."""
        if self.closed:
            return
        self.closed = True
        recorder = self._recorder
        try:
            if recorder.failed is None:  # closed by the test itself: written now, kept only if it fails
                written = recorder.scratch() / f"{self._index}.zip"
                self._context.tracing.stop(path=str(written))
                recorder.pending[self._index] = written
            elif recorder.failed:
                TRACES.mkdir(parents=True, exist_ok=True)
                self._screenshots()
                self._context.tracing.stop(path=str(recorder.trace_path(self._index)))
            else:
                self._context.tracing.stop()
        except Exception as exc:  # a context whose browser is gone: its trace is lost, the close goes on
            recorder.note(f"trace not written: {exc}")
        self._context.close(**kwargs)

    def __enter__(self) -> RecordedContext:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __getattr__(self, name: str) -> Any:
        return getattr(self._context, name)


class RecordedBrowser:
    """The session's Chromium as one test sees it: ``new_context`` answers a :class:`RecordedContext`; every other
    attribute is the browser's own."""

    def __init__(self, browser: Any, recorder: Recorder) -> None:
        self._browser = browser
        self.recorder = recorder

    def new_context(self, **kwargs: Any) -> RecordedContext:
        return RecordedContext(self._browser.new_context(**kwargs), self.recorder)

    def new_page(self, **kwargs: Any) -> Any:
        return self.new_context(**kwargs).new_page()

    def __getattr__(self, name: str) -> Any:
        return getattr(self._browser, name)


#: The stash key of a test's :class:`Recorder`.
RECORDER = pytest.StashKey[Recorder]()
