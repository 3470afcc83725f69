"""Set-up screen: the bat (file or form), the procedure, the rig, and the devices at a glance."""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, ClassVar

from rich.text import Text
from textual import work
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Horizontal, Vertical
from textual.screen import Screen
from textual.widgets import Button, Footer, Header, Input, Label, Select, Static

from rig.core.errors import ConfigError, RigError
from rig.tui.messages import OpenHistory, StartRun
from rig.tui.rigs import (
    LOADING,
    PROCEDURES,
    ConsoleSettings,
    DeviceReport,
    RigChoice,
    RunJob,
    chart_state,
    read_devices,
)

if TYPE_CHECKING:  # the bat model (pydantic) and the renderings load after the first paint
    from rig.core.bat import BatSpec
    from rig.core.config import RigConfig

# (field, label, unit) of the bat form, in BatSpec's names
BAT_FIELDS = (
    ("id", "id", ""),
    ("length_in", "length", "in"),
    ("weight_oz", "weight", "oz"),
    ("hoop_hz", "hoop", "Hz"),
    ("balance_point_in", "balance", "in from knob"),
    ("moi_kgm2", "MOI", "kg m² (pivot)"),
)


class SetupScreen(Screen[None]):
    """Choose what to certify and where; `s` starts the run."""

    DEFAULT_CSS = """
    SetupScreen #columns { height: auto; }
    SetupScreen .box { border: round $primary; height: auto; padding: 0 1; }
    SetupScreen #bat { width: 42; }
    SetupScreen #right { width: 1fr; height: auto; }
    SetupScreen .row { height: 1; margin-bottom: 0; }
    SetupScreen .row Label { width: 10; }
    SetupScreen .row Input { width: 1fr; }
    SetupScreen .row .unit { width: auto; min-width: 3; padding-left: 1; color: $text-muted; }
    SetupScreen .row Select { width: 1fr; }
    SetupScreen #devices { height: auto; min-height: 7; }
    SetupScreen #actions { height: 3; padding: 1 1 0 1; }
    SetupScreen #start { margin-right: 2; }
    SetupScreen #status { width: 1fr; height: 2; }
    """
    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("s", "start", "Start run"),
        Binding("r", "read_devices", "Read devices"),
        Binding("h", "history", "History"),
        Binding("escape", "leave_field", "Leave field", show=False),
    ]

    def __init__(self, settings: ConsoleSettings) -> None:
        super().__init__()
        self.settings = settings
        self._status_configs: dict[str, RigConfig] = {}
        self.report: DeviceReport | None = None
        self._read_key = ""
        self._barrels_filled = False

    # -- layout ------------------------------------------------------------------------------
    def compose(self) -> ComposeResult:
        yield Header()
        with Horizontal(id="columns"):
            with Vertical(id="bat", classes="box"):
                yield self._row("file", Input(self.settings.bat_path, id="bat-file", compact=True), "")
                for name, label, unit in BAT_FIELDS:
                    yield self._row(label, Input(id=f"bat-{name}", compact=True), unit)
                barrels = Select[str]([], id="bat-barrel", prompt="...", compact=True)  # after the paint
                yield self._row("barrel", barrels, "")
            with Vertical(id="right"):
                with Vertical(id="choice", classes="box"):
                    procs = [(label, ref) for label, ref in PROCEDURES]
                    if self.settings.procedure not in {ref for _, ref in PROCEDURES}:
                        procs.append((self.settings.procedure, self.settings.procedure))
                    yield self._row(
                        "procedure",
                        Select(
                            procs,
                            value=self.settings.procedure,
                            id="procedure",
                            allow_blank=False,
                            compact=True,
                        ),
                        "",
                    )
                    # who performs the test: recorded with the new run, its report's "test performed by"
                    yield self._row(
                        "operator", Input(id="operator", placeholder="your name", compact=True), ""
                    )
                    rigs = [(r.label, r.key) for r in self.settings.rigs]
                    yield self._row(
                        "rig",
                        Select(rigs, value=rigs[0][1], id="rig", allow_blank=False, compact=True),
                        "",
                    )
                yield Static(Text("reading the devices...", style="dim"), id="devices", classes="box")
        with Horizontal(id="actions"):
            yield Button("Start run (s)", id="start", variant="success", compact=True)
            yield Static("", id="status")
        yield Footer()

    @staticmethod
    def _row(label: str, widget: Input | Select[str], unit: str) -> Horizontal:
        parts: list[Label | Input | Select[str]] = [Label(label), widget]
        if unit:
            parts.append(Label(unit, classes="unit"))
        return Horizontal(*parts, classes="row")

    def on_mount(self) -> None:
        self.sub_title = "set-up"
        self.query_one("#bat", Vertical).border_title = "Bat"
        self.query_one("#choice", Vertical).border_title = "Procedure and rig"
        self.query_one("#devices", Static).border_title = "Devices"
        if not self.settings.bat_path:
            self.call_after_refresh(self._fill_barrels)
        loaded = bool(self.settings.bat_path) and self.load_bat_file(self.settings.bat_path)
        # a bat to type: the file field takes the keys; a bat given: s (or Enter) starts
        self.query_one("#start" if loaded else "#bat-file").focus()
        self._read_key = self.rig.key  # the rig selector's first Changed event must not read again
        self.call_after_refresh(self.action_read_devices)  # opening the rig loads much: after the first paint

    # -- the bat -----------------------------------------------------------------------------
    def _fill_barrels(self) -> None:
        """The barrel choices, from the bat model (loaded now, not before the first paint)."""
        if self._barrels_filled:
            return
        from rig.core.bat import Barrel  # light (pydantic): not under LOADING, so never waits

        select: Select[str] = self.query_one("#bat-barrel", Select)
        select.set_options([(b.value, b.value) for b in Barrel])
        select.value = next(iter(Barrel)).value
        self._barrels_filled = True

    def load_bat_file(self, path: str) -> bool:
        """Fill the form from a bat file; a bad file shows why and leaves the form as it was."""
        from rig.core.bat import BatSpec

        self._fill_barrels()
        try:
            bat = BatSpec.load(path)
        except ConfigError as exc:
            self.show_status(f"bat file: {exc}", error=True)
            return False
        for name, _, _ in BAT_FIELDS:
            value = getattr(bat, name)
            text = "" if value is None else f"{value:g}" if isinstance(value, float) else str(value)
            self.query_one(f"#bat-{name}", Input).value = text
        self.query_one("#bat-barrel", Select).value = bat.barrel.value
        self.show_status(f"bat {bat.id} loaded from {path}: s or Enter starts")
        return True

    def bat_from_form(self) -> BatSpec:
        """The bat as the form describes it; a bad value raises ConfigError naming the field."""
        from pydantic import ValidationError

        from rig.core.bat import BatSpec

        self._fill_barrels()
        data: dict[str, object] = {}
        for name, _, _ in BAT_FIELDS:
            value = self.query_one(f"#bat-{name}", Input).value.strip()
            if value:
                data[name] = value
        data["barrel"] = self.query_one("#bat-barrel", Select).value
        try:
            return BatSpec.model_validate(data)
        except ValidationError as exc:
            first = exc.errors()[0]
            raise ConfigError(first["msg"], source="bat", field=".".join(map(str, first["loc"]))) from None

    def on_input_submitted(self, event: Input.Submitted) -> None:
        if event.input.id == "bat-file" and event.value.strip() and self.load_bat_file(event.value.strip()):
            self.query_one("#start", Button).focus()  # the next key starts (s or Enter)

    # -- the rig -----------------------------------------------------------------------------
    @property
    def rig(self) -> RigChoice:
        """The chosen rig."""
        key = self.query_one("#rig", Select).value
        return next((r for r in self.settings.rigs if r.key == key), self.settings.rigs[0])

    def on_select_changed(self, event: Select.Changed) -> None:
        if event.select.id == "rig" and event.value != self._read_key:
            self.action_read_devices()

    def action_read_devices(self) -> None:
        """Read every device's status in a worker."""
        self.query_one("#devices", Static).update(Text("reading the devices...", style="dim"))
        self._read_key = self.rig.key
        self._read_devices(self.rig)

    @work(thread=True, exclusive=True, group="devices", exit_on_error=False)
    def _read_devices(self, choice: RigChoice) -> None:
        try:
            config = self._status_configs.get(choice.key) or choice.config()
            self._status_configs[choice.key] = config
            report = read_devices(config, self.settings.device_lock)
            report = replace(report, checks=chart_state(self.settings.db, config))
        except RigError as exc:
            report = DeviceReport(errors=(str(exc),))
        self.app.call_from_thread(self._show_devices, report)

    def _show_devices(self, report: DeviceReport) -> None:
        from rig.tui.render import STATE_STYLE, interlock_text

        self.report = report
        text = Text()
        if report.cannon is not None:
            st = report.cannon
            text.append("cannon  ")
            text.append(st.state.value, style=STATE_STYLE.get(st.state, ""))
            text.append(f"  {st.pressure_kpa:.1f} kPa, {st.shots} shots\n")
            text.append_text(interlock_text(st))
            text.append("\n")
        if report.clamp is not None:
            c = report.clamp
            text.append(f"clamp   {'locked' if c.locked else 'released'} at {c.position_mm:.1f} mm\n")
        if report.gates is not None:
            g = report.gates
            text.append(f"gates   {g.gates}, tick {g.tick_ns:g} ns, {g.bits}-bit\n")
        if report.environment is not None:
            e = report.environment
            text.append(f"lab     {e.temperature_c:.1f} C, {e.humidity_pct:.0f} % RH\n")
        if report.checks is not None:
            line, refused = report.checks
            text.append("checks  ")
            text.append(f"{line}\n", style="bold red" if refused else "")
        for err in report.errors:
            text.append(f"{err}\n", style="bold red")
        text.rstrip()
        self.query_one("#devices", Static).update(text)
        if report.errors:
            self.show_status("a device did not answer: see Devices", error=True)

    # -- actions -----------------------------------------------------------------------------
    def show_status(self, message: str, error: bool = False) -> None:
        """One line under the form: what happened last."""
        self.query_one("#status", Static).update(Text(message, style="bold red" if error else ""))

    def on_button_pressed(self, event: Button.Pressed) -> None:
        if event.button.id == "start":
            self.action_start()

    def action_leave_field(self) -> None:
        """Esc in a field: focus the start button, so the letter keys work again."""
        self.query_one("#start", Button).focus()

    def action_history(self) -> None:
        """Past runs and their reports."""
        self.post_message(OpenHistory(self.rig))

    def build_job(self) -> RunJob:
        """The run the form describes, rehearsed; raises RigError (with the field) when something is wrong."""
        with LOADING:  # loaded at the first start (or by the warm-up), not before the first paint
            from rig.protocols.procedure import Procedure
            from rig.tui.jobs import prepare_job, refuse_break_in

        chosen = str(self.query_one("#procedure", Select).value)
        refuse_break_in(chosen)  # its rolling prompts are not in the console yet
        bat = self.bat_from_form()
        procedure = Procedure.load(chosen)
        tested_by = self.query_one("#operator", Input).value.strip() or None
        return prepare_job(self.settings, procedure, bat, self.rig, tested_by)

    def action_start(self) -> None:
        """Check the set-up (a dry run) and open the run screen."""
        try:
            job = self.build_job()
        except RigError as exc:
            self.show_status(str(exc), error=True)
            self.notify(str(exc), title="Cannot start", severity="error")
            return
        self.show_status("")
        self.post_message(StartRun(job, then=self.action_read_devices))
