"""History screen: the recorded runs and, for the highlighted one, its report."""

from __future__ import annotations

from typing import Any, ClassVar

from textual import work
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import VerticalScroll
from textual.screen import Screen
from textual.widgets import DataTable, Footer, Header, Static

from rig.certification import history
from rig.core.errors import RigError
from rig.core.events import ONE_SHOT_KIND as ONE_SHOT
from rig.report.record import run_record
from rig.resume import recorded_inputs
from rig.store import RunSummary, Store, shown_status
from rig.tui.messages import StartRun
from rig.tui.report import one_shot_summary, record_summary
from rig.tui.rigs import LOADING, ConsoleSettings, RigChoice, RunJob


def _certificate_md(record: dict[str, Any]) -> str | None:
    """The certificate as Markdown without its figures (a terminal shows no PNG: drawing them took
    seconds per run), or None when rig.report cannot build it."""
    try:
        with LOADING:
            from rig.report.cert_doc import to_markdown
            from rig.report.certificate import build

        return to_markdown(build(record, {}), None)
    except Exception:  # a certificate that cannot be built still leaves the summary to read
        return None


class ReportView(Static):
    """A run's report: Markdown drawn by rich (Textual's Markdown widget took seconds for a
    certificate's tables); `source` keeps the Markdown shown."""

    source = ""

    def show(self, markdown: str) -> None:
        """Show `markdown` (the first call also loads rich's Markdown)."""
        from rich.markdown import Markdown

        self.source = markdown
        self.update(Markdown(markdown))


class HistoryScreen(Screen[None]):
    """Past runs, newest first; Enter shows a run's report, r resumes an open run."""

    DEFAULT_CSS = """
    HistoryScreen #runs { height: 8; border: round $primary; }
    HistoryScreen #report { height: 1fr; border: round $primary-darken-2; }
    """
    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("escape,b", "back", "Back"),
        Binding("enter", "show", "Report", show=False),
        Binding("r", "resume", "Resume"),
        # the list keeps the focus: these scroll the report below it (no Tab needed)
        Binding("pagedown", "report(1)", "Report", key_display="PgDn", priority=True),
        Binding("pageup", "report(-1)", "Report up", key_display="PgUp", show=False, priority=True),
    ]

    def __init__(self, settings: ConsoleSettings, rig: RigChoice | None = None) -> None:
        super().__init__()
        self.settings, self.rig = settings, rig or settings.rigs[0]
        self.runs: list[RunSummary] = []

    def compose(self) -> ComposeResult:
        yield Header()
        yield DataTable(id="runs", cursor_type="row", zebra_stripes=True)
        with VerticalScroll(id="report"):
            yield ReportView(id="report-text")
        yield Footer()

    def on_mount(self) -> None:
        self.sub_title = "history"
        table = self.query_one("#runs", DataTable)
        table.border_title = "Runs (newest first)"
        self.query_one("#report", VerticalScroll).border_title = "Report (PgDn / PgUp)"
        self._report("Choose a run.")
        table.add_columns("run", "procedure", "bat", "started (UTC)", "status", "verdict")
        try:
            with Store.open(self.settings.db) as store:
                self.runs = list(reversed(store.runs()))
                status = {r.run_id: shown_status(store, r) for r in self.runs}  # as `rig runs` shows it
        except RigError as exc:
            self._report(f"**Cannot read the records:** {exc}")
            return
        for r in self.runs:
            started = r.started_utc[:16].replace("T", " ")
            table.add_row(
                r.run_id[:8], r.procedure, r.bat_id, started, status[r.run_id], r.verdict or "", key=r.run_id
            )
        if not self.runs:
            self._report(f"No runs recorded yet in `{self.settings.db}`.")
        table.focus()

    def _selected(self) -> RunSummary | None:
        table = self.query_one("#runs", DataTable)
        if not self.runs or table.cursor_row < 0:
            return None
        return self.runs[min(table.cursor_row, len(self.runs) - 1)]

    def on_data_table_row_highlighted(self, event: DataTable.RowHighlighted) -> None:
        self.action_show()

    def action_show(self) -> None:
        """Show the highlighted run's report (built in a worker: reading the record takes a moment)."""
        run = self._selected()
        if run is not None:
            self._report(f"Reading run {run.run_id[:8]}: the certificate takes a few seconds...")
            self._load(run.run_id)

    def _report(self, markdown: str) -> None:
        self.query_one("#report-text", ReportView).show(markdown)
        self.query_one("#report", VerticalScroll).scroll_home(animate=False)

    def action_report(self, pages: int) -> None:
        """Scroll the report a page down (1) or up (-1) while the list keeps the focus."""
        scroll = self.query_one("#report", VerticalScroll)
        scroll.scroll_page_down(animate=False) if pages > 0 else scroll.scroll_page_up(animate=False)

    @work(thread=True, exclusive=True, group="report", exit_on_error=False)
    def _load(self, run_id: str) -> None:
        try:
            with Store.open(self.settings.db) as store:
                record = run_record(store, run_id)
                one_shot = store.run(run_id).procedure == ONE_SHOT
            text = one_shot_summary(record) if one_shot else _certificate_md(record) or record_summary(record)
        except Exception as exc:  # an unreadable record is reported, not raised
            text = f"**Cannot build the report:** {exc}"
        self.app.call_from_thread(self._report, text)

    def action_back(self) -> None:
        """Back to where the history was opened from."""
        self.dismiss(None)

    def action_resume(self) -> None:
        """Resume the highlighted run if it never finished, on the rig chosen in set-up."""
        run = self._selected()
        if run is None or run.status != "running":  # finished, or ended without a verdict
            self.notify("choose a run that is interrupted (not finished or ended)", severity="warning")
            return
        if getattr(self.app, "run_active", False):
            self.notify("a run is already active", severity="warning")
            return
        try:
            with Store.open(self.settings.db) as store:
                past = history(store, run.run_id)
                recorded = recorded_inputs(store, run.run_id)  # a run that never started: its RunCreated's
            procedure, bat = recorded.procedure, recorded.bat
            config = self.rig.config(bat, procedure)
            job = RunJob(procedure, bat, config, self.rig.label, run_id=run.run_id, rig=self.rig)
        except (RigError, ValueError) as exc:
            self.notify(str(exc), title="Cannot resume", severity="error")
            return
        self.post_message(StartRun(job, past, replace=True))
