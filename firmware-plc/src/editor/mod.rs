//! The keypad/LCD front panel: program editor, run screen and fault log screen.
//!
//! Sans-IO: the application feeds [`Key`]s to [`Editor::key`] together with the program
//! (which it owns, because the VM runs it too) and gets back a [`Request`] (save, load,
//! run, stop, new, clear the fault log) to carry out; it reports how that went with
//! [`Editor::notify`]. [`Editor::render`] draws the current page into a [`Screen`] from a
//! [`View`] of the program and the live state. The same code drives a 20x4 and a 16x2 LCD.
//!
//! The key map is in `docs/keymap.md`. Decisions where panel.md is silent:
//! * Editing is refused while the PLC runs (the VM executes the same program; a
//!   half-entered line would run). Browsing, save, STOP and the other pages work.
//! * A field being edited is a pending value shown on the LCD; it is written into the
//!   program when the field is left (`5`, `4`/`6` to the next field, or any command key)
//!   and discarded with `*`. Every pending value is valid by construction.
//! * Insert and delete shift lines inside the line's own section only (000-149 or
//!   150-999), so no line ever changes section; insert is refused when the section's
//!   last line is in use.
//! * The editor knows whether the program differs from the one last loaded or saved
//!   ([`Editor::modified`]): `D` `0` (new) and `D` `1`..`4` (load) ask before discarding
//!   unsaved changes (`DISCARD EDITS? #=YES`; `#` confirms, any other key cancels), as a
//!   user of the real device loses work the same way. A program equal to the saved one
//!   after edits that undo each other still counts as changed (no 6 KB copy to compare).
//! * `A` (RUN) verifies first; on an error the listing jumps to the bad line and the
//!   status row shows `NNN:reason`, and no RUN is requested.

pub(crate) mod calendar;
mod choice;
mod key;
mod pages;
mod screen;
pub(crate) mod text;

pub use key::Key;
pub use screen::{Screen, MAX_COLS, MAX_ROWS};

use crate::storage::{FaultEntry, LoadReport, OtherCopy, ProgramUse, StorageError, SLOTS};
use pages::Line;
use shared_protocol::link::DriveState;
use shared_protocol::program::{
    safety_settings, uses_safety, verify, Instruction, Program, Section, ShortText, LINES,
    PLC_FIRST_LINE,
};
use text::Text;

/// What the application must do after a key.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Request {
    /// Save the program into slot 1..=4, then [`Editor::notify`] the outcome.
    Save(u8),
    /// Load slot 1..=4 into the program, then notify the outcome.
    Load(u8),
    /// The program verified; start RUN. `slot` is the slot it was loaded from or saved
    /// to, when unchanged since (for the boot record), else `None`.
    Run {
        slot: Option<u8>,
    },
    Stop,
    /// The editor has emptied the program (`D` `0`).
    New,
    /// Acknowledge the drive's latched faults (`*` `9`, any page): the drive returns to
    /// IDLE when the cause is gone; it never restarts by itself, a new RUN is needed.
    AckFaults,
    /// Erase the stored fault log.
    ClearFaultLog,
    /// Keys `*` `7` (any page, also in RUN): switch remote service on or off
    /// (service.md 4: the keypad's consent to guarded service requests).
    ToggleRemote,
}

/// Outcomes the application reports back; shown on the status row until the next key.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Notice {
    Saved {
        slot: u8,
    },
    SaveFailed {
        slot: u8,
        error: StorageError,
    },
    /// A load (from a key, or at power-up) succeeded; says so when a copy was bad.
    Loaded(LoadReport),
    LoadFailed {
        slot: u8,
        error: StorageError,
    },
    /// RUN was refused further on (e.g. the drive rejected its section): the line and a
    /// short reason (at most 16 characters).
    RunRefused {
        line: Option<u16>,
        reason: ShortText,
    },
    /// A program was written into `slot` over the service port (service.md 3).
    Written {
        slot: u8,
    },
    /// Any other short text (at most 20 characters).
    Text(&'static str),
    /// RUN started a program that uses the safety functions: `NOT RATED SIG 3A7F`
    /// (safety.md 10).
    NotRated {
        signature: u16,
    },
}

/// A run-time warning for the status row, e.g. `DIV0` at line 163.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Warning<'a> {
    pub text: &'a str,
    pub line: Option<u16>,
}

/// The live state the run screen shows; the application fills it every refresh.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RunView<'a> {
    /// The PLC is in RUN.
    pub running: bool,
    /// Valid frames arrive from the drive.
    pub link_up: bool,
    pub drive_state: DriveState,
    /// Output frequency, 0.1 Hz.
    pub freq_dhz: i16,
    pub reverse: bool,
    /// The newest drive fault (code of drive.md), `None` when there is none to show.
    pub fault: Option<u8>,
    /// The 4 `LCD` value fields, `None` when no `LCD` instruction filled them.
    pub lcd: [Option<i16>; 4],
    /// The PLC's own run-time warning (`DIV0` at a line).
    pub warning: Option<Warning<'a>>,
    /// The drive's run-time warning as its status reports it (e.g. `PWF 488Hz @ 000`).
    pub drive_warning: Option<Warning<'a>>,
    /// The safety functions as the drive reports them (`None`: link down).
    pub safety: Option<SafetyView>,
    /// Remote service is on (keys `*` `7`): the status row shows a `*` after the PLC
    /// state, so whoever stands at the machine sees that a PC may run and acknowledge.
    pub remote: bool,
}

/// The safety functions on the status row (safety.md 10): one `S:` item per requested
/// function, in bit order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SafetyView {
    /// Requested functions (bit n = function n).
    pub requested: u16,
    /// Status bits (requested and in the safe state).
    pub status: u16,
    /// When each function was last requested (the `now_ms` clock), for `DEC n.ns`.
    pub since_ms: [u32; 12],
}

impl Default for RunView<'_> {
    fn default() -> Self {
        RunView {
            running: false,
            link_up: false,
            drive_state: DriveState::Boot,
            freq_dhz: 0,
            reverse: false,
            fault: None,
            lcd: [None; 4],
            warning: None,
            drive_warning: None,
            safety: None,
            remote: false,
        }
    }
}

/// Everything [`Editor::render`] draws from.
#[derive(Debug, Clone, Copy)]
pub struct View<'a> {
    pub program: &'a Program,
    pub run: RunView<'a>,
    /// Stored faults, newest first.
    pub fault_log: &'a [FaultEntry],
    /// A monotonic millisecond clock: rotates the hints of the status row.
    pub now_ms: u32,
}

/// The three pages, cycled with `B`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Page {
    Listing,
    Run,
    FaultLog,
}

impl Page {
    fn next(self) -> Page {
        match self {
            Page::Listing => Page::Run,
            Page::Run => Page::FaultLog,
            Page::FaultLog => Page::Listing,
        }
    }
}

/// The fields of a listing line the cursor can be on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Field {
    Mnemonic,
    Operand,
    Constant,
}

/// A pending two-key command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Prefix {
    /// `C`: save into a slot.
    Save,
    /// `D`: load a slot, or `0` for a new program.
    Load,
    /// `*`: line operations (insert, delete, clear, check) or clearing the fault log.
    Line,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    Browse,
    /// Editing the cursor field of the cursor line; `digit` is the constant digit.
    Edit {
        pending: Option<Instruction>,
        digit: u8,
    },
    Prefix(Prefix),
    /// `#` and up to three digits of a line number.
    Goto {
        value: u16,
        digits: u8,
    },
    /// `D` `n` with unsaved changes: `#` discards them and carries out `then`, any other
    /// key cancels (`DISCARD EDITS? #=YES`).
    ConfirmDiscard {
        then: Discard,
    },
}

/// What discards the program in RAM: a load (`D` `1`..`4`) or a new program (`D` `0`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Discard {
    Load(u8),
    New,
}

type Message = heapless::String<{ MAX_COLS }>;

/// The front-panel state machine.
#[derive(Debug, Clone)]
pub struct Editor {
    cols: u8,
    rows: u8,
    page: Page,
    line: u16,
    top: u16,
    field: Field,
    mode: Mode,
    message: Option<Message>,
    log_index: core::cell::Cell<u8>,
    /// When the current message was first drawn (ms) and the alerts standing then: with a
    /// fault or warning present it gives way to them after [`pages::MESSAGE_MS`], and at
    /// once to an alert that came after it, so a message never hides a fault.
    message_drawn_at: core::cell::Cell<Option<(u32, pages::AlertKey)>>,
    slot: Option<u8>,
    modified: bool,
    /// How a storage job holds the program now (see [`Editor::set_program_use`]).
    program_use: Option<ProgramUse>,
}

const LAST_LINE: u16 = LINES as u16 - 1;

fn section_of(line: u16) -> Section {
    Section::of_line(line).unwrap_or(Section::Plc)
}

/// Fields the cursor can visit on a line holding `i`.
fn field_available(i: Option<&Instruction>, f: Field) -> bool {
    match f {
        Field::Mnemonic => true,
        Field::Operand => i.is_some_and(|i| i.operand.is_some()),
        Field::Constant => i.is_some_and(|i| i.operand.is_some_and(|o| o.is_k())),
    }
}

impl Editor {
    /// An editor for a `cols` x `rows` LCD (20x4 or 16x2; clamped to 1..=20 x 1..=4).
    pub fn new(cols: u8, rows: u8) -> Editor {
        Editor {
            cols: cols.clamp(1, MAX_COLS as u8),
            rows: rows.clamp(1, MAX_ROWS as u8),
            page: Page::Listing,
            line: 0,
            top: 0,
            field: Field::Mnemonic,
            mode: Mode::Browse,
            message: None,
            log_index: core::cell::Cell::new(0),
            message_drawn_at: core::cell::Cell::new(None),
            slot: None,
            modified: false,
            program_use: None,
        }
    }

    /// How a queued or running storage job holds the program (the application sets it
    /// before each key): while a save reads it or a load rewrites it, edits, NEW, save and
    /// load are refused ("EEPROM BUSY"); RUN is refused only while a load rewrites it.
    /// A save may start, and run, in RUN: it is done a page per pass and never
    /// starves the link.
    pub fn set_program_use(&mut self, u: Option<ProgramUse>) {
        self.program_use = u;
    }

    /// A blank screen of this editor's size.
    pub fn screen(&self) -> Screen {
        Screen::new(self.cols, self.rows)
    }

    pub fn page(&self) -> Page {
        self.page
    }

    /// The cursor line.
    pub fn line(&self) -> u16 {
        self.line
    }

    pub fn field(&self) -> Field {
        self.field
    }

    /// Whether a field is being edited.
    pub fn editing(&self) -> bool {
        matches!(self.mode, Mode::Edit { .. })
    }

    /// The slot the program came from or went to, if unchanged since.
    pub fn slot(&self) -> Option<u8> {
        if self.modified {
            None
        } else {
            self.slot
        }
    }

    /// The slot the program was last loaded from or saved to, edited since or not (the
    /// service's `Status`: "the slot in RAM"; [`Editor::modified`] says whether edited).
    pub fn loaded_slot(&self) -> Option<u8> {
        self.slot
    }

    /// Whether the program changed since it was last loaded or saved (the dirty flag):
    /// `D` `0` and `D` `1`..`4` ask before discarding it, and a host (the PC panel)
    /// asks before quitting.
    pub fn modified(&self) -> bool {
        self.modified
    }

    /// The application replaced the program in RAM by other means than a load (e.g. the
    /// PC panel put a program file there): it is unsaved, and belongs to no slot.
    pub fn mark_modified(&mut self) {
        self.modified = true;
    }

    /// Whether keys are awaited to finish something: a field being edited, a two-key
    /// command (`C`, `D`, `*`, `#`) or a confirmation. `*` cancels any of them (the PC
    /// panel's Esc sends `*` then, and quits otherwise).
    pub fn awaiting_keys(&self) -> bool {
        self.mode != Mode::Browse
    }

    /// The status-row message, if one is showing.
    pub fn message(&self) -> Option<&str> {
        self.message.as_deref()
    }

    /// Show a page (the application may switch to the run screen when RUN starts).
    pub fn show_page(&mut self, page: Page) {
        self.page = page;
    }

    /// Rows of the listing (all but the status row).
    fn listing_rows(&self) -> u16 {
        u16::from(self.rows.saturating_sub(1).max(1))
    }

    fn set_message(&mut self, text: &str) {
        let mut s = Message::new();
        for ch in text.chars().take(usize::from(self.cols)) {
            let _ = s.push(ch);
        }
        self.message = Some(s);
        self.message_drawn_at.set(None);
    }

    /// Report the outcome of a request (or a power-up load).
    pub fn notify(&mut self, notice: Notice) {
        let narrow = self.cols < 20;
        match notice {
            Notice::Saved { slot } => {
                self.slot = Some(slot);
                self.modified = false;
                self.set_message(Line::new().str("SAVED IN SLOT ").dec(slot.into()));
            }
            Notice::Written { slot } if narrow => {
                self.set_message(Line::new().char('S').dec(slot.into()).str(" WRITTEN (SVC)"));
            }
            Notice::Written { slot } => self.set_message(
                Line::new()
                    .str("SLOT ")
                    .dec(slot.into())
                    .str(" WRITTEN (SVC)"),
            ),
            Notice::SaveFailed { slot, error } => {
                self.set_message(
                    Line::new()
                        .str("SAVE S")
                        .dec(slot.into())
                        .str(" FAILED ")
                        .str(storage_short(error)),
                );
            }
            Notice::Loaded(r) => {
                self.slot = Some(r.slot);
                self.modified = false;
                self.line = 0;
                self.top = 0;
                self.field = Field::Mnemonic;
                match r.other {
                    OtherCopy::Bad(_) => self.set_message(
                        Line::new()
                            .char('S')
                            .dec(r.slot.into())
                            .str(if narrow { " " } else { ":COPY " })
                            .char(r.used.other().letter())
                            .str(" BAD,USED ")
                            .char(r.used.letter()),
                    ),
                    _ => self.set_message(Line::new().str("LOADED SLOT ").dec(r.slot.into())),
                }
            }
            Notice::LoadFailed { slot, error } => {
                self.set_message(
                    Line::new()
                        .char('S')
                        .dec(slot.into())
                        .char(' ')
                        .str(storage_short(error)),
                );
            }
            Notice::RunRefused { line, reason } => match line {
                Some(l) => {
                    self.goto_line(l);
                    self.set_message(Line::new().dec0(l.into(), 3).char(':').short_text(reason));
                }
                None => self.set_message(Line::new().str("NO RUN:").short_text(reason)),
            },
            Notice::Text(t) => self.set_message(t),
            // 16 columns: the signature must stay readable.
            Notice::NotRated { signature } => self.set_message(
                Line::new()
                    .str(if self.cols < 18 {
                        "NOT RATED "
                    } else {
                        "NOT RATED SIG "
                    })
                    .hex4(signature),
            ),
        }
    }

    fn goto_line(&mut self, line: u16) {
        self.page = Page::Listing;
        self.line = line.min(LAST_LINE);
        self.field = Field::Mnemonic;
        if self.line < self.top || self.line >= self.top + self.listing_rows() {
            // A jump shows the target at the top, with what follows it below.
            self.top = self.line;
        }
        self.follow();
    }

    /// Keep the cursor line inside the visible window.
    fn follow(&mut self) {
        let n = self.listing_rows();
        if self.line < self.top {
            self.top = self.line;
        } else if self.line >= self.top + n {
            self.top = self.line + 1 - n;
        }
        self.top = self.top.min(LINES as u16 - n.min(LINES as u16));
    }

    fn move_lines(&mut self, delta: i32) {
        let l = (i32::from(self.line) + delta).clamp(0, i32::from(LAST_LINE));
        self.line = l as u16;
        self.follow();
    }

    /// Handle one key. `running` says whether the PLC is in RUN now.
    pub fn key(&mut self, key: Key, program: &mut Program, running: bool) -> Option<Request> {
        self.message = None;
        match self.mode {
            Mode::Browse => self.command_or_page_key(key, program, running),
            Mode::Prefix(p) => {
                self.mode = Mode::Browse;
                self.prefix_key(p, key, program, running)
            }
            Mode::Goto { value, digits } => {
                self.goto_key(key, value, digits);
                None
            }
            Mode::Edit { pending, digit } => self.edit_key(key, pending, digit, program, running),
            Mode::ConfirmDiscard { then } => {
                self.mode = Mode::Browse;
                if key == Key::Hash {
                    self.discard(then, program, running)
                } else {
                    self.set_message("CANCELLED");
                    None
                }
            }
        }
    }

    /// `D` `n`: at once when nothing is unsaved, else after `#` confirms.
    fn ask_discard(
        &mut self,
        then: Discard,
        program: &mut Program,
        running: bool,
    ) -> Option<Request> {
        if self.refuse_while_running(running) {
            return None;
        }
        if self.modified {
            self.mode = Mode::ConfirmDiscard { then };
            return None;
        }
        self.discard(then, program, running)
    }

    fn discard(&mut self, then: Discard, program: &mut Program, running: bool) -> Option<Request> {
        // Checked again: RUN or a storage job may have started since the question.
        if self.refuse_while_running(running) {
            return None;
        }
        match then {
            Discard::Load(slot) => Some(Request::Load(slot)),
            Discard::New => {
                // In place: a 6 KB temporary would not fit the MCU's stack budget.
                program.lines.fill(None);
                self.slot = None;
                self.modified = false;
                self.goto_line(0);
                self.set_message("NEW PROGRAM");
                Some(Request::New)
            }
        }
    }

    fn command_or_page_key(
        &mut self,
        key: Key,
        program: &mut Program,
        running: bool,
    ) -> Option<Request> {
        match key {
            Key::A => self.run_stop(program, running),
            Key::B => {
                self.page = self.page.next();
                None
            }
            Key::C => {
                self.mode = Mode::Prefix(Prefix::Save);
                None
            }
            Key::D => {
                self.mode = Mode::Prefix(Prefix::Load);
                None
            }
            Key::Star => {
                self.mode = Mode::Prefix(Prefix::Line);
                None
            }
            Key::Hash => {
                self.mode = Mode::Goto {
                    value: 0,
                    digits: 0,
                };
                None
            }
            Key::Digit(d) => {
                match self.page {
                    Page::Listing => self.browse_digit(d, program, running),
                    Page::FaultLog => match d {
                        2 => self.log_index.set(self.log_index.get().saturating_sub(1)),
                        8 => self
                            .log_index
                            .set(self.log_index.get().saturating_add(1).min(31)),
                        _ => {}
                    },
                    Page::Run => {}
                }
                None
            }
        }
    }

    fn run_stop(&mut self, program: &Program, running: bool) -> Option<Request> {
        if running {
            return Some(Request::Stop);
        }
        if self.program_use == Some(ProgramUse::Writes) {
            self.set_message("EEPROM BUSY");
            return None;
        }
        match verify(program) {
            Ok(()) => Some(Request::Run { slot: self.slot() }),
            Err(e) => {
                self.goto_line(e.line);
                self.set_message(
                    Line::new()
                        .dec0(e.line.into(), 3)
                        .char(':')
                        .short_text(e.kind.short()),
                );
                None
            }
        }
    }

    /// Edits and loads: refused in RUN, and while a storage job holds the program.
    fn refuse_while_running(&mut self, running: bool) -> bool {
        if running {
            self.set_message("STOP FIRST (A)");
            return true;
        }
        self.refuse_while_storage_busy()
    }

    fn refuse_while_storage_busy(&mut self) -> bool {
        if self.program_use.is_some() {
            self.set_message("EEPROM BUSY");
            return true;
        }
        false
    }

    fn prefix_key(
        &mut self,
        p: Prefix,
        key: Key,
        program: &mut Program,
        running: bool,
    ) -> Option<Request> {
        let Key::Digit(d) = key else {
            self.set_message("CANCELLED");
            return None;
        };
        match p {
            Prefix::Save if (1..=SLOTS).contains(&d) => {
                // Allowed in RUN: the save runs a page per pass.
                if self.refuse_while_storage_busy() {
                    return None;
                }
                Some(Request::Save(d))
            }
            Prefix::Load if (1..=SLOTS).contains(&d) => {
                self.ask_discard(Discard::Load(d), program, running)
            }
            Prefix::Load if d == 0 => self.ask_discard(Discard::New, program, running),
            Prefix::Line if d == 9 => Some(Request::AckFaults),
            Prefix::Line if d == 7 => Some(Request::ToggleRemote),
            Prefix::Line if self.page == Page::FaultLog && d == 0 => {
                self.log_index.set(0);
                Some(Request::ClearFaultLog)
            }
            Prefix::Line if self.page == Page::FaultLog => {
                self.set_message("CANCELLED");
                None
            }
            Prefix::Line => {
                self.line_op(d, program, running);
                None
            }
            _ => {
                self.set_message("CANCELLED");
                None
            }
        }
    }

    fn line_op(&mut self, d: u8, program: &mut Program, running: bool) {
        self.page = Page::Listing;
        match d {
            5 => match verify(program) {
                // safety.md 8: the signature of a program using the safety functions.
                // On a 16-column LCD the signature comes first.
                Ok(()) if uses_safety(program) => self.set_message(
                    Line::new()
                        .str(if self.cols >= 19 {
                            "PROGRAM OK "
                        } else {
                            "OK "
                        })
                        .str("SIG ")
                        .hex4(safety_settings(program.lines.iter()).signature()),
                ),
                Ok(()) => self.set_message("PROGRAM OK"),
                Err(e) => {
                    self.goto_line(e.line);
                    self.set_message(
                        Line::new()
                            .dec0(e.line.into(), 3)
                            .char(':')
                            .short_text(e.kind.short()),
                    );
                }
            },
            1 | 3 | 0 if self.refuse_while_running(running) => {}
            1 => self.insert_line(program),
            3 => self.delete_line(program),
            0 => {
                if let Some(l) = program.lines.get_mut(usize::from(self.line)) {
                    if l.take().is_some() {
                        self.modified = true;
                    }
                }
                self.field = Field::Mnemonic;
            }
            _ => self.set_message("CANCELLED"),
        }
    }

    /// Last line of the cursor line's section.
    fn section_end(&self) -> usize {
        if self.line < PLC_FIRST_LINE {
            usize::from(PLC_FIRST_LINE) - 1
        } else {
            LINES - 1
        }
    }

    fn insert_line(&mut self, program: &mut Program) {
        let at = usize::from(self.line);
        let end = self.section_end();
        if program.lines.get(end).is_some_and(|l| l.is_some()) {
            self.set_message("SECTION FULL");
            return;
        }
        if let Some(s) = program.lines.get_mut(at..=end) {
            // A copy loop, not `rotate_right`: its general rotation code and
            // `memmove` cost 1.8 KB of flash for a one-place shift.
            for i in (1..s.len()).rev() {
                if let Some(&prev) = s.get(i - 1) {
                    if let Some(l) = s.get_mut(i) {
                        *l = prev;
                    }
                }
            }
            if let Some(first) = s.first_mut() {
                *first = None;
            }
        }
        self.field = Field::Mnemonic;
        self.modified = true;
    }

    fn delete_line(&mut self, program: &mut Program) {
        let at = usize::from(self.line);
        let end = self.section_end();
        if let Some(s) = program.lines.get_mut(at..=end) {
            // A copy loop, not `rotate_left` (see `insert_line`).
            for i in 1..s.len() {
                if let Some(&next) = s.get(i) {
                    if let Some(l) = s.get_mut(i - 1) {
                        *l = next;
                    }
                }
            }
            if let Some(last) = s.last_mut() {
                *last = None;
            }
        }
        self.field = Field::Mnemonic;
        self.modified = true;
    }

    fn goto_key(&mut self, key: Key, value: u16, digits: u8) {
        match key {
            Key::Digit(d) => {
                let value = value * 10 + u16::from(d);
                if digits + 1 >= 3 {
                    self.mode = Mode::Browse;
                    self.goto_line(value);
                } else {
                    self.mode = Mode::Goto {
                        value,
                        digits: digits + 1,
                    };
                }
            }
            Key::Hash if digits > 0 => {
                self.mode = Mode::Browse;
                self.goto_line(value);
            }
            _ => {
                self.mode = Mode::Browse;
                self.set_message("CANCELLED");
            }
        }
    }

    fn browse_digit(&mut self, d: u8, program: &Program, running: bool) {
        let current = program.get(self.line);
        match d {
            2 => self.move_lines(-1),
            8 => self.move_lines(1),
            1 => self.move_lines(-10),
            7 => self.move_lines(10),
            3 => self.move_lines(-100),
            9 => self.move_lines(100),
            0 => {
                // Next used line, round the program.
                let start = usize::from(self.line) + 1;
                let next = (0..LINES)
                    .map(|k| (start + k) % LINES)
                    .find(|&n| program.lines.get(n).is_some_and(|l| l.is_some()));
                match next {
                    Some(n) => self.goto_line(n as u16),
                    None => self.set_message("PROGRAM EMPTY"),
                }
            }
            4 => {
                self.field = match self.field {
                    Field::Constant => Field::Operand,
                    _ => Field::Mnemonic,
                }
            }
            6 => {
                let next = match self.field {
                    Field::Mnemonic => Field::Operand,
                    _ => Field::Constant,
                };
                if field_available(current, next) {
                    self.field = next;
                }
            }
            5 if !self.refuse_while_running(running) => {
                self.mode = Mode::Edit {
                    pending: current.copied(),
                    digit: 0,
                };
            }
            _ => {}
        }
        // Moving to a shorter line pulls the cursor back to a field that exists there.
        let here = program.get(self.line);
        while !field_available(here, self.field) {
            self.field = match self.field {
                Field::Constant => Field::Operand,
                _ => Field::Mnemonic,
            };
        }
    }

    fn commit(&mut self, pending: Option<Instruction>, program: &mut Program) {
        if let Some(l) = program.lines.get_mut(usize::from(self.line)) {
            if *l != pending {
                *l = pending;
                self.modified = true;
            }
        }
        self.mode = Mode::Browse;
        if !field_available(pending.as_ref(), self.field) {
            self.field = Field::Mnemonic;
        }
    }

    fn edit_key(
        &mut self,
        key: Key,
        pending: Option<Instruction>,
        digit: u8,
        program: &mut Program,
        running: bool,
    ) -> Option<Request> {
        let section = section_of(self.line);
        let d = match key {
            Key::Star => {
                self.mode = Mode::Browse;
                if !field_available(program.get(self.line), self.field) {
                    self.field = Field::Mnemonic;
                }
                self.set_message("CANCELLED");
                return None;
            }
            Key::Digit(d) => d,
            _ => {
                self.commit(pending, program);
                return self.command_or_page_key(key, program, running);
            }
        };
        let mut pending = pending;
        let mut digit = digit;
        match (self.field, d) {
            (_, 5) => {
                self.commit(pending, program);
                return None;
            }
            (Field::Mnemonic, 2 | 8 | 1 | 7) => {
                let delta = match d {
                    2 => -1,
                    8 => 1,
                    1 => -10,
                    _ => 10,
                };
                pending = choice::step_mnemonic(pending, section, delta);
            }
            (Field::Mnemonic, 6) if field_available(pending.as_ref(), Field::Operand) => {
                self.field = Field::Operand;
            }
            (Field::Operand, 4) => self.field = Field::Mnemonic,
            (Field::Operand, 6) if field_available(pending.as_ref(), Field::Constant) => {
                self.field = Field::Constant;
                digit = 0;
            }
            (Field::Operand, 2 | 8 | 1 | 7 | 3 | 9) => {
                if let Some(i) = pending {
                    pending = Some(match d {
                        2 => choice::step_operand(i, section, -1),
                        8 => choice::step_operand(i, section, 1),
                        1 => choice::step_operand(i, section, -10),
                        7 => choice::step_operand(i, section, 10),
                        3 => choice::step_operand_class(i, section, false),
                        _ => choice::step_operand_class(i, section, true),
                    });
                }
            }
            (Field::Constant, 4) if digit == 0 => self.field = Field::Operand,
            (Field::Constant, 4) => digit -= 1,
            (Field::Constant, 6) => digit = (digit + 1).min(3),
            (Field::Constant, 2 | 8) => {
                if let Some(i) = pending {
                    pending = Some(choice::step_digit(i, section, digit, d == 8));
                }
            }
            _ => {}
        }
        self.mode = Mode::Edit { pending, digit };
        None
    }

    /// Draw the current page.
    pub fn render(&self, view: &View<'_>, out: &mut Screen) {
        *out = Screen::new(self.cols, self.rows);
        match self.page {
            Page::Listing => {
                self.render_listing(view, out);
                if self.rows > 1 {
                    let mut s = pages::Line::new();
                    pages::status_text(self, view, &mut s);
                    out.put(self.rows - 1, 0, &s);
                }
            }
            Page::Run => pages::run_page(self, view, out),
            Page::FaultLog => pages::fault_log_page(self, view, out),
        }
    }

    fn render_listing(&self, view: &View<'_>, out: &mut Screen) {
        let wide = self.cols >= 20;
        let n = self.listing_rows();
        for r in 0..n {
            let line = self.top + r;
            if usize::from(line) >= LINES {
                break;
            }
            let instr = match self.mode {
                Mode::Edit { pending, .. } if line == self.line => pending,
                _ => view.program.get(line).copied(),
            };
            let row = r as u8;
            let cols = pages::ListingCols::new(wide);
            if wide && line == self.line {
                out.put(row, 0, ">");
            }
            out.put(row, cols.number, Text::new().dec0(line.into(), 3));
            if let Some(i) = instr {
                out.put(row, cols.mnemonic, i.mnemonic.text());
                if let Some(op) = i.operand {
                    out.put(row, cols.operand, Text::new().operand(&op));
                    if op.is_k() {
                        out.put(row, cols.constant, Text::new().dec0(i.constant.into(), 4));
                    }
                }
            }
            if line == self.line {
                let (col, blink) = match self.mode {
                    Mode::Edit { digit, .. } => {
                        let c = cols.of(self.field)
                            + if self.field == Field::Constant {
                                digit
                            } else {
                                0
                            };
                        (c, false)
                    }
                    _ => (cols.of(self.field), true),
                };
                out.cursor = Some((row, col));
                out.blink = blink;
            }
        }
    }
}

fn storage_short(e: StorageError) -> &'static str {
    match e {
        StorageError::NoSuchSlot(_) => "NO SUCH SLOT",
        StorageError::Empty(_) => "EMPTY",
        StorageError::Damaged(_) => "DAMAGED",
        StorageError::TooBig => "TOO BIG",
        StorageError::VerifyFailed => "VERIFY ERR",
        StorageError::Eeprom(_) => "EEPROM ERR",
        StorageError::Busy => "EEPROM BUSY",
    }
}

#[cfg(test)]
mod tests;
