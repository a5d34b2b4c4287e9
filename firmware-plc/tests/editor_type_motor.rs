//! panel.md: "the source's full motor example can be typed in on the keypad, and the
//! result equals the assembled text (a test types it key by key)".
//!
//! The typist works like a person: it looks at the LCD after every key and presses `8`
//! (or the faster `7`/`9` jumps) until the field shows what the listing says. Nothing
//! here knows the editor's choice order. Then the program is saved into the EEPROM model
//! with `C1`, the editor is cleared with `D0`, loaded back with `D1`, and compared.

use firmware_plc::editor::{Editor, Key, Notice, Request, RunView, Screen, View};
use firmware_plc::storage::image::{program_image, ImageOptions};
use firmware_plc::storage::layout::copy_addr;
use firmware_plc::storage::{MemEeprom, Storage};
use shared_protocol::program::{assemble, operand_text, parse_operand, Instruction, Program};

const MOTOR: &str = include_str!("../../shared-protocol/programs/motor.plc");

struct Panel {
    ed: Editor,
    program: Program,
    storage: Storage<MemEeprom>,
    keys: usize,
}

impl Panel {
    fn new(cols: u8, rows: u8) -> Panel {
        Panel {
            ed: Editor::new(cols, rows),
            program: Program::default(),
            storage: Storage::new(MemEeprom::new()),
            keys: 0,
        }
    }

    /// Press one key and carry out what the editor asks, as the application would.
    fn press(&mut self, c: char) {
        self.keys += 1;
        let key = Key::from_char(c).unwrap();
        match self.ed.key(key, &mut self.program, false) {
            None | Some(Request::New) => {}
            Some(Request::Save(slot)) => {
                self.storage.save(slot, &self.program).unwrap();
                self.ed.notify(Notice::Saved { slot });
            }
            Some(Request::Load(slot)) => {
                let r = self.storage.load(slot, &mut self.program).unwrap();
                self.ed.notify(Notice::Loaded(r));
            }
            Some(other) => panic!("unexpected request {other:?}"),
        }
    }

    fn keys(&mut self, s: &str) {
        s.chars().for_each(|c| self.press(c));
    }

    fn screen(&self) -> Screen {
        let mut s = self.ed.screen();
        self.ed.render(
            &View {
                program: &self.program,
                run: RunView::default(),
                fault_log: &[],
                now_ms: 0,
            },
            &mut s,
        );
        s
    }

    /// Text of a listing column on the cursor row.
    fn column(&self, field: usize) -> String {
        let s = self.screen();
        let (row, _) = s.cursor.expect("cursor on the listing");
        let text = s.row(row).to_string();
        let (wide, cols) = if s.cols() >= 20 {
            (true, [5usize, 10, 14])
        } else {
            (false, [4usize, 8, 12])
        };
        let _ = wide;
        let start = cols[field];
        let end = match field {
            0 => cols[1] - 1,
            1 => cols[2] - 1,
            _ => cols[2] + 4,
        };
        text[start..end].trim().to_string()
    }

    /// Press `key` until `done` holds, at most `limit` times.
    fn until(&mut self, key: char, limit: usize, what: &str, done: impl Fn(&Panel) -> bool) {
        for _ in 0..limit {
            if done(self) {
                return;
            }
            self.press(key);
        }
        assert!(done(self), "could not reach {what}: {:?}", self.screen());
    }

    fn type_line(&mut self, n: u16, i: &Instruction) {
        self.keys(&format!("#{n:03}"));
        self.press('5');
        let m = i.mnemonic.text();
        self.until('8', 60, m, |p| p.column(0) == m);
        if let Some(op) = i.operand {
            self.press('6');
            let want = operand_text(&op).to_string();
            let class = op.class();
            self.until('9', 30, &want, |p| {
                parse_operand(&p.column(1)).is_some_and(|o| o.class() == class)
            });
            self.until('7', 10, &want, |p| {
                parse_operand(&p.column(1)).is_some_and(|o| o.index() + 10 > op.index())
            });
            self.until('8', 10, &want, |p| p.column(1) == want);
            if op.is_k() {
                self.press('6');
                let digits = format!("{:04}", i.constant);
                for (k, d) in digits.chars().enumerate() {
                    self.until('8', 10, &digits, |p| p.column(2).chars().nth(k) == Some(d));
                    if k < 3 {
                        self.press('6');
                    }
                }
            }
        }
        self.press('5');
        assert_eq!(self.program.get(n), Some(i), "line {n:03}");
    }
}

fn type_motor(cols: u8, rows: u8) -> usize {
    let expected = assemble(MOTOR).unwrap();
    let mut panel = Panel::new(cols, rows);
    for (n, line) in expected.lines.iter().enumerate() {
        if let Some(i) = line {
            panel.type_line(n as u16, i);
        }
    }
    assert_eq!(panel.program, expected, "typed program");
    assert!(panel.ed.modified());
    let typed_keys = panel.keys;
    panel.keys("C1");
    assert_eq!(panel.ed.slot(), Some(1));
    // The slot holds byte for byte what `hil-sim asm -o` puts in an off-board image.
    let image = program_image(&expected, &ImageOptions::default()).unwrap();
    let a = usize::from(copy_addr(1, 0).unwrap());
    let end = usize::from(copy_addr(2, 0).unwrap());
    assert_eq!(
        panel.storage.eeprom().image()[a..end],
        image[a..end],
        "slot 1 (copies A and B)"
    );
    panel.keys("D0");
    assert_eq!(panel.program, Program::default());
    panel.keys("D1");
    assert_eq!(panel.program, expected, "program loaded from the EEPROM");
    // And it runs: RUN verifies and asks for the run of slot 1.
    assert_eq!(
        panel.ed.key(Key::A, &mut panel.program, false),
        Some(Request::Run { slot: Some(1) })
    );
    println!("{cols}x{rows}: motor program typed with {typed_keys} keys");
    typed_keys
}

#[test]
fn motor_program_typed_on_a_20x4_lcd() {
    type_motor(20, 4);
}

#[test]
fn motor_program_typed_on_a_16x2_lcd() {
    type_motor(16, 2);
}
