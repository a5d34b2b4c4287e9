//! Drawing: listing columns, the status row, the run page and the fault log page.

use super::calendar;
use super::text::Text;
use super::{Editor, Field, Mode, Page, Prefix, Screen, View, MAX_COLS};
use crate::storage::FaultEntry;
use shared_protocol::link::fault_text;
use shared_protocol::safety::{SafetyFunction, FUNCTION_MASK};
use shared_protocol::service::{app_fault_of, log_name, EVENT_LOG_CLEARED, EVENT_PROGRAM_WRITTEN};

/// One row of text, long enough for any row before clipping.
pub(super) type Line = Text;

/// How long each status-row item stays before the next one rotates in.
const ROTATE_MS: u32 = 2000;

/// How long a transient message (saved, loaded, verifier error...) keeps the status row
/// while a fault or warning is waiting to be shown. Without alerts it stays until a key.
pub(super) const MESSAGE_MS: u32 = 3000;

/// Column of each listing field: `>NNN MNEM OPR CCCC` on 20 columns, `NNN MNE OPR CCCC`
/// on 16 (every mnemonic has at most 3 characters, so nothing is lost).
#[derive(Clone, Copy)]
pub(super) struct ListingCols {
    pub number: u8,
    pub mnemonic: u8,
    pub operand: u8,
    pub constant: u8,
}

impl ListingCols {
    pub fn new(wide: bool) -> ListingCols {
        if wide {
            ListingCols {
                number: 1,
                mnemonic: 5,
                operand: 10,
                constant: 14,
            }
        } else {
            ListingCols {
                number: 0,
                mnemonic: 4,
                operand: 8,
                constant: 12,
            }
        }
    }

    pub fn of(self, f: Field) -> u8 {
        match f {
            Field::Mnemonic => self.mnemonic,
            Field::Operand => self.operand,
            Field::Constant => self.constant,
        }
    }
}

/// Tenths as `12.3` (sign dropped: the direction is shown separately).
fn tenths(v: i16) -> Text {
    let v = u32::from(v.unsigned_abs());
    let mut t = Text::new();
    t.dec(v / 10).char('.').dec(v % 10);
    t
}

/// A field value, or `-` when no `LCD` instruction filled it.
fn field_value(v: Option<i16>) -> Text {
    let mut t = Text::new();
    match v {
        Some(v) => t.int(i32::from(v)),
        None => t.char('-'),
    };
    t
}

fn fault_line(code: u8, s: &mut Line) {
    s.char('F')
        .dec(u32::from(code))
        .char(' ')
        .str(fault_text(code));
}

fn warning_line(w: Option<super::Warning<'_>>, s: &mut Line) -> bool {
    let Some(w) = w else {
        return false;
    };
    match w.line {
        Some(l) => s.str("W:").str(w.text).str(" @ ").dec0(u32::from(l), 3),
        None => s.str("W:").str(w.text),
    };
    true
}

/// Whether a fault, a warning (the PLC's or the drive's) or a requested safety function
/// waits to be shown.
fn any_alert(view: &View<'_>) -> bool {
    view.run.fault.is_some()
        || view.run.warning.is_some()
        || view.run.drive_warning.is_some()
        || sf_requested(view) != 0
}

/// Which alerts stand (the fault's code, a PLC warning, a drive warning, the requested
/// safety functions): a change while a message is up is a new alert, shown at once.
pub(super) type AlertKey = (Option<u8>, bool, bool, u16);

fn alert_key(view: &View<'_>) -> AlertKey {
    (
        view.run.fault,
        view.run.warning.is_some(),
        view.run.drive_warning.is_some(),
        sf_requested(view),
    )
}

fn sf_requested(view: &View<'_>) -> u16 {
    view.run.safety.map_or(0, |s| s.requested & FUNCTION_MASK)
}

/// One safety function's status-row item (safety.md 10): `S:STO ON`, `S:SS1 OK`,
/// `S:SOS NOK` (status 0 with a fault latched), `S:SS1 DEC 3.2s` (requested, not yet safe:
/// the time since the request).
fn safety_line(view: &View<'_>, bit: u8, s: &mut Line) {
    let Some(sv) = view.run.safety else { return };
    let Some(f) = SafetyFunction::from_bit(bit) else {
        return;
    };
    let name = f.name();
    if f == SafetyFunction::Sto {
        s.str("S:STO ON");
    } else if sv.status & f.mask() != 0 {
        s.str("S:").str(name).str(" OK");
    } else if view.run.fault.is_some() {
        s.str("S:").str(name).str(" NOK");
    } else {
        let since = sv.since_ms.get(usize::from(bit)).copied().unwrap_or(0);
        let ds = (view.now_ms.wrapping_sub(since) / 100).min(99_999);
        s.str("S:")
            .str(name)
            .str(" DEC ")
            .dec(ds / 10)
            .char('.')
            .dec(ds % 10)
            .char('s');
    }
}

/// The prompt of a pending command or edit, or the transient message.
fn prompt(ed: &Editor, view: &View<'_>, s: &mut Line) -> bool {
    let narrow = ed.cols < 20;
    if let Some(m) = &ed.message {
        let now = view.now_ms;
        let key = alert_key(view);
        let (drawn, standing) = ed.message_drawn_at.get().unwrap_or((now, key));
        ed.message_drawn_at.set(Some((drawn, standing)));
        let new_alert = key != standing;
        if !any_alert(view) || (now.wrapping_sub(drawn) < MESSAGE_MS && !new_alert) {
            s.str(m);
            return true;
        }
    }
    let faulted = view.run.fault.is_some();
    let text = match ed.mode {
        Mode::Browse => return false,
        Mode::Prefix(Prefix::Save) if narrow => "SAVE SLOT 1-4?",
        Mode::Prefix(Prefix::Save) => "SAVE TO SLOT 1-4?",
        Mode::Prefix(Prefix::Load) if narrow => "LOAD 1-4 0=NEW",
        Mode::Prefix(Prefix::Load) => "LOAD SLOT 1-4 0=NEW",
        // With a fault standing, `*` `9` (acknowledge) is what the user most likely needs.
        Mode::Prefix(Prefix::Line) if ed.page == Page::FaultLog && faulted => "0=CLR LOG 9=ACK",
        Mode::Prefix(Prefix::Line) if ed.page == Page::FaultLog => "0=CLEAR FAULT LOG",
        Mode::Prefix(Prefix::Line) if faulted && narrow => "9ACK 1IN 3DL 0CL",
        Mode::Prefix(Prefix::Line) if faulted => "9=ACK 1INS 3DEL 0CLR",
        Mode::Prefix(Prefix::Line) if narrow => "1IN 3DL 0CL 5CHK",
        Mode::Prefix(Prefix::Line) => "1INS 3DEL 0CLR 5CHK",
        Mode::ConfirmDiscard { .. } if narrow => "DISCARD? #=YES",
        Mode::ConfirmDiscard { .. } => "DISCARD EDITS? #=YES",
        Mode::Goto { value, digits } => {
            s.str("GOTO LINE ");
            if digits > 0 {
                s.dec0(u32::from(value), usize::from(digits));
            }
            for _ in digits..3 {
                s.char('_');
            }
            return true;
        }
        Mode::Edit { .. } => match ed.field {
            Field::Mnemonic if narrow => "2/8 SEL 5OK *ESC",
            Field::Mnemonic => "2/8 SELECT 5OK *ESC",
            Field::Operand if narrow => "2/8 1/7 3/9 5OK",
            Field::Operand => "2/8 1/7 3/9 5OK *ESC",
            Field::Constant if narrow => "2/8 DIG 4/6 5OK",
            Field::Constant => "2/8 DIGIT 4/6 5OK",
        },
    };
    s.str(text);
    true
}

/// The hint that takes turns with the alerts: with a fault standing, how to acknowledge
/// it (`*` `9`) and RUN/STOP; otherwise the page's first hint.
fn main_hint(ed: &Editor, view: &View<'_>, s: &mut Line) {
    if view.run.fault.is_none() {
        hint(ed, view, 0, s);
        return;
    }
    let text = match (view.run.running, ed.cols < 20) {
        (true, false) => "*9=ACK FAULT A=STOP",
        (false, false) => "*9=ACK FAULT A=RUN",
        (true, true) => "*9 ACK A STOP",
        (false, true) => "*9 ACK A RUN",
    };
    s.str(text);
}

/// The help hints of a page, most important first.
fn hint(ed: &Editor, view: &View<'_>, n: usize, s: &mut Line) -> usize {
    let narrow = ed.cols < 20;
    let running = view.run.running;
    let first = match (running, narrow) {
        (false, false) => "A=RUN C=SAVE D=LOAD",
        (true, false) => "A=STOP B=NEXT PAGE",
        (false, true) => "A RUN C SV D LD",
        (true, true) => "A STOP B PAGE",
    };
    let second = if narrow {
        "D0 NEW B PAGE"
    } else {
        "D0=NEW B=NEXT PAGE"
    };
    let page: &[&str] = match (ed.page, narrow) {
        (Page::Listing, false) => &["5=EDIT #=GOTO *=LINE", "1/7:10 3/9:100 0:NXT"],
        (Page::Listing, true) => &["5EDIT #GOTO *LINE", "1/7 3/9 0 JUMP"],
        (Page::FaultLog, false) => &["2/8 MORE *0=CLEAR"],
        (Page::FaultLog, true) => &["2/8 MORE *0 CLR"],
        (Page::Run, _) => &[],
    };
    let count = 2 + page.len();
    let text = match n % count {
        0 => first,
        1 => second,
        k => page.get(k - 2).copied().unwrap_or(first),
    };
    s.str(text);
    count
}

/// The status row: prompt or message first; otherwise faults and warnings alternating
/// with the main hint, or the hints in turn.
pub(super) fn status_text(ed: &Editor, view: &View<'_>, s: &mut Line) {
    if prompt(ed, view, s) {
        return;
    }
    let tick = (view.now_ms / ROTATE_MS) as usize;
    // The alerts present, in this order: fault, PLC warning, drive warning, then one per
    // requested safety function in bit order (3 + bit).
    let mut alerts: heapless::Vec<u8, 15> = heapless::Vec::new();
    for (k, present) in [
        view.run.fault.is_some(),
        view.run.warning.is_some(),
        view.run.drive_warning.is_some(),
    ]
    .into_iter()
    .enumerate()
    {
        if present {
            let _ = alerts.push(k as u8);
        }
    }
    let requested = sf_requested(view);
    for bit in 0..12u8 {
        if requested & (1 << bit) != 0 {
            let _ = alerts.push(3 + bit);
        }
    }
    if alerts.is_empty() {
        let mut scratch = Line::new();
        let count = hint(ed, view, 0, &mut scratch);
        hint(ed, view, tick % count, s);
        return;
    }
    // Alerts, then the main hint (so RUN/STOP/save/load stay discoverable).
    match alerts.get(tick % (alerts.len() + 1)) {
        Some(0) => fault_line(view.run.fault.unwrap_or(0), s),
        Some(1) => {
            warning_line(view.run.warning, s);
        }
        Some(2) => {
            warning_line(view.run.drive_warning, s);
        }
        Some(k) => safety_line(view, k - 3, s),
        None => main_hint(ed, view, s),
    }
}

fn pad_row(out: &mut Screen, row: u8, s: &str) {
    let blank = [b' '; MAX_COLS];
    out.put(row, 0, core::str::from_utf8(&blank).unwrap_or(""));
    out.put(row, 0, s);
}

/// PLC state, link, drive state, frequency and direction.
fn run_status(view: &View<'_>, narrow: bool, s: &mut Line) {
    let r = &view.run;
    let plc = if r.running { "RUN" } else { "STOP" };
    // Remote service on (service.md 4): a `*` in the blank column after the PLC state
    // (16 columns: before the direction).
    let mark = if r.remote { '*' } else { ' ' };
    if !r.link_up {
        s.left(plc, 4).char(mark).str("LINK LOST");
        return;
    }
    let dir = if r.reverse { 'R' } else { 'F' };
    let freq = tenths(r.freq_dhz);
    if narrow {
        s.left(plc, 4)
            .left(r.drive_state.name(), 5)
            .right(&freq, 5)
            .char(mark)
            .char(dir);
    } else {
        s.left(plc, 4)
            .char(mark)
            .left(r.drive_state.name(), 5)
            .char(' ')
            .right(&freq, 5)
            .str("Hz ")
            .char(dir);
    }
}

fn fields_row(view: &View<'_>, first: usize, narrow: bool, s: &mut Line) {
    let a = view.run.lcd.get(first).copied().flatten();
    let b = view.run.lcd.get(first + 1).copied().flatten();
    field_pair(a, b, first as u32 + 1, narrow, s);
}

/// Fields `na` and `na + 1` with their values (`-` for none), as the run page shows them.
fn field_pair(a: Option<i16>, b: Option<i16>, na: u32, narrow: bool, s: &mut Line) {
    let nb = na + 1;
    let (a, b) = (field_value(a), field_value(b));
    if narrow {
        s.dec(na)
            .char('=')
            .left(&a, 6)
            .dec(nb)
            .char('=')
            .left(&b, 6);
    } else {
        s.dec(na)
            .char(':')
            .right(&a, 6)
            .str("   ")
            .dec(nb)
            .char(':')
            .right(&b, 6);
    }
}

/// Run page: status, the 4 `LCD` fields, and the status row (faults, warnings, hints).
pub(super) fn run_page(ed: &Editor, view: &View<'_>, out: &mut Screen) {
    let narrow = ed.cols < 20;
    let mut s = Line::new();
    run_status(view, narrow, &mut s);
    pad_row(out, 0, &s);
    let last = ed.rows - 1;
    if ed.rows >= 4 {
        for (row, first) in [(1u8, 0usize), (2, 2)] {
            let mut s = Line::new();
            fields_row(view, first, narrow, &mut s);
            pad_row(out, row, &s);
        }
    } else if ed.rows >= 3 {
        let mut s = Line::new();
        fields_row(view, 0, narrow, &mut s);
        pad_row(out, 1, &s);
    }
    if last == 0 {
        return;
    }
    let mut s = Line::new();
    if ed.rows >= 3 || prompt(ed, view, &mut s) {
        if ed.rows >= 3 {
            status_text(ed, view, &mut s);
        }
        pad_row(out, last, &s);
        return;
    }
    // Two rows: the second rotates through the fields, alerts and the main hint.
    let fields_34 = view.run.lcd.iter().skip(2).any(|v| v.is_some());
    let mut items: heapless::Vec<u8, 6> = heapless::Vec::new();
    let _ = items.push(0);
    if fields_34 {
        let _ = items.push(1);
    }
    if view.run.fault.is_some() {
        let _ = items.push(2);
    }
    if view.run.warning.is_some() {
        let _ = items.push(3);
    }
    if view.run.drive_warning.is_some() {
        let _ = items.push(5);
    }
    let _ = items.push(4);
    let tick = (view.now_ms / ROTATE_MS) as usize;
    match items.get(tick % items.len()).copied().unwrap_or(4) {
        0 => fields_row(view, 0, true, &mut s),
        1 => fields_row(view, 2, true, &mut s),
        2 => fault_line(view.run.fault.unwrap_or(0), &mut s),
        3 => {
            warning_line(view.run.warning, &mut s);
        }
        5 => {
            warning_line(view.run.drive_warning, &mut s);
        }
        _ => main_hint(ed, view, &mut s),
    }
    pad_row(out, last, &s);
}

/// Fault log page: one entry (newest first), scrolled with 2/8. Each entry rotates two
/// pairs of rows: its text and its values (the first two `LCD` fields when it was
/// logged, as the run page shows them), and its time of day (`CLOCK NOT SET` without)
/// and its power-up and uptime.
pub(super) fn fault_log_page(ed: &Editor, view: &View<'_>, out: &mut Screen) {
    let narrow = ed.cols < 20;
    let n = view.fault_log.len();
    let last = ed.rows - 1;
    let index = usize::from(ed.log_index.get()).min(n.saturating_sub(1));
    ed.log_index.set(index as u8);
    let entry = view.fault_log.get(index);
    let mut s = Line::new();
    match entry {
        None => {
            s.str("FAULT LOG EMPTY");
        }
        Some(e) => {
            if !narrow {
                s.str("LOG ");
            }
            s.dec0(index as u32 + 1, 2)
                .char('/')
                .dec0(n as u32, 2)
                .str(" F")
                .dec(u32::from(e.code))
                .char(' ')
                .str(field_io_name(e.code).unwrap_or(log_name(e.code)));
        }
    }
    pad_row(out, 0, &s);
    let tick = (view.now_ms / ROTATE_MS) as usize;
    // Which entry rows: 0 text, 1 values, 2 time of day, 3 power-up and uptime.
    let (a, b) = if tick % 2 == 1 { (1, 3) } else { (0, 2) };
    if ed.rows >= 4 {
        for (row, item) in [(1, a), (2, b)] {
            s = Line::new();
            if let Some(e) = entry {
                entry_row(e, item, narrow, &mut s);
            }
            pad_row(out, row, &s);
        }
        s = Line::new();
        status_text(ed, view, &mut s);
        pad_row(out, last, &s);
        return;
    }
    if last == 0 {
        return;
    }
    s = Line::new();
    let item = tick % 5;
    let prompted = prompt(ed, view, &mut s);
    match entry {
        Some(e) if !prompted && item < 4 => entry_row(e, item, narrow, &mut s),
        Some(_) if !prompted => main_hint(ed, view, &mut s),
        _ if s.is_empty() => status_text(ed, view, &mut s),
        _ => {}
    }
    pad_row(out, last, &s);
}

/// Row `item` of a log entry: 0 its text, 1 its values (the first two `LCD` fields when
/// it was logged, as the run page shows them; the text when it has none), 2 its time of
/// day (`CLOCK NOT SET` without), 3 its power-up and uptime.
fn entry_row(e: &FaultEntry, item: usize, narrow: bool, s: &mut Line) {
    let (v0, v1) = (e.value(0), e.value(1));
    match item {
        1 if v0.is_some() || v1.is_some() => field_pair(v0, v1, 1, narrow, s),
        0 | 1 => log_text(e.code, s),
        2 => wall_line(e.wall(), s),
        _ => {
            let t = e.uptime_s;
            s.str("PWR ")
                .dec(u32::from(e.power_cycle))
                .str(" UP ")
                .dec(t / 3600)
                .char(':')
                .dec0((t / 60) % 60, 2)
                .char(':')
                .dec0(t % 60, 2);
        }
    }
}

/// The short name of a field I/O fault (200-203), also its text on the LCD, in the
/// shield profile only (the default image never logs one and keeps its flash; the long
/// texts are the PC's, `shared_protocol::service::LogText`).
#[cfg(feature = "field-io")]
fn field_io_name(code: u8) -> Option<&'static str> {
    shared_protocol::service::field_fault_name(code)
}

#[cfg(not(feature = "field-io"))]
fn field_io_name(_code: u8) -> Option<&'static str> {
    None
}

/// A log entry's text: the drive's fault text, `application fault n` (the texts of an
/// application's faults are in its profile, on the PC), or the event's.
fn log_text(code: u8, s: &mut Line) {
    match app_fault_of(code) {
        Some(n) => {
            s.str("application fault ").dec(u32::from(n));
        }
        None => {
            s.str(match code {
                EVENT_LOG_CLEARED => "fault log cleared",
                EVENT_PROGRAM_WRITTEN => "program written svc",
                c => field_io_name(c).unwrap_or(fault_text(c)),
            });
        }
    }
}

/// The time of day of `wall` (seconds since 2000-01-01 00:00:00 UTC) as
/// `2026-11-29 10:15:07` (16 columns: `2026-11-29 10:15`), or `CLOCK NOT SET`.
fn wall_line(wall: Option<u32>, s: &mut Line) {
    let Some(t) = wall else {
        s.str("CLOCK NOT SET");
        return;
    };
    let (y, m, d) = calendar::date(t / 86_400);
    s.dec(y)
        .char('-')
        .dec0(m, 2)
        .char('-')
        .dec0(d, 2)
        .char(' ')
        .dec0(t / 3600 % 24, 2)
        .char(':')
        .dec0(t / 60 % 60, 2)
        .char(':')
        .dec0(t % 60, 2);
}
