//! The stepped storage jobs: at most one EEPROM transfer of at most
//! one page per step, never an access during a write cycle, the same bytes and the same
//! power-fail safety as the synchronous operations.

use firmware_plc::storage::{
    BootChange, Eeprom, EepromError, Job, JobDone, MemEeprom, ProgramUse, Storage, StorageError,
    EEPROM_BYTES, PAGE_BYTES, QUEUE_JOBS, WRITE_CYCLE_LIMIT_US,
};
use shared_protocol::program::{Instruction, Mnemonic, Operand, Program, LINES};
use shared_protocol::units::Micros;

/// A program of `n` used lines in the PLC section (several runs).
fn program(n: usize, seed: u16) -> Program {
    let mut p = Program::default();
    let mut k = 0;
    let mut line = 150;
    while k < n && line < LINES {
        if line % 37 != 0 {
            p.lines[line] = Some(Instruction {
                mnemonic: Mnemonic::Ld,
                operand: Some(Operand::K((k % 100) as u8)),
                constant: (seed as usize + k) as u16 % 10_000,
            });
            k += 1;
        }
        line += 1;
    }
    p
}

/// An EEPROM that counts the bytes moved per transfer and the transfers since a mark.
struct Counting {
    inner: MemEeprom,
    transfers: u32,
    largest: usize,
    polls: u32,
    /// Write cycles that never end (the chip is gone after a write).
    stuck: bool,
    /// The page write with this number (0 = the first) breaks on the bus (an I2C
    /// timeout): the chip has latched the first half of its bytes, the board's bus
    /// clear ends it with a STOP (which starts the write cycle) and the call returns
    /// `Bus`.
    break_write: Option<u32>,
    writes: u32,
}

impl Counting {
    fn new(inner: MemEeprom) -> Self {
        Counting {
            inner,
            transfers: 0,
            largest: 0,
            polls: 0,
            stuck: false,
            break_write: None,
            writes: 0,
        }
    }
}

impl Eeprom for Counting {
    fn read(&mut self, addr: u16, buf: &mut [u8]) -> Result<(), EepromError> {
        self.transfers += 1;
        self.largest = self.largest.max(buf.len());
        self.inner.read(addr, buf)
    }
    fn start_write(&mut self, addr: u16, data: &[u8]) -> Result<(), EepromError> {
        self.transfers += 1;
        self.largest = self.largest.max(data.len());
        self.writes += 1;
        if self.break_write == Some(self.writes - 1) {
            self.inner.start_write(addr, &data[..data.len() / 2])?;
            return Err(EepromError::Bus);
        }
        self.inner.start_write(addr, data)
    }
    fn ready(&mut self) -> Result<bool, EepromError> {
        self.polls += 1;
        if self.stuck {
            return Ok(false);
        }
        self.inner.ready()
    }
}

/// Runs the queue to its end, one step per ms, asserting at most one transfer of at most
/// one page per step; returns the outcomes and the number of steps.
fn drain(s: &mut Storage<Counting>, p: &mut Program, t: &mut u64) -> (Vec<JobDone>, u32) {
    let mut done = Vec::new();
    let mut steps = 0;
    while s.busy() {
        let before = s.eeprom().transfers;
        *t += 1000;
        let step = s.step(Micros(*t), p);
        let moved = s.eeprom().transfers - before;
        assert!(moved <= 1, "{moved} transfers in one step");
        assert!(!step.used_bus || moved == 1 || step.done.is_some() || moved == 0);
        if let Some(d) = step.done {
            done.push(d);
        }
        steps += 1;
        assert!(steps < 100_000, "the queue never empties");
    }
    assert!(s.eeprom().largest <= PAGE_BYTES);
    (done, steps)
}

#[test]
fn a_stepped_save_and_load_move_one_page_per_step_and_never_meet_a_busy_chip() {
    let mut mem = MemEeprom::new();
    // The chip stays busy for three polls after every write (about 3 ms of passes).
    mem.set_busy_polls(3);
    let mut s = Storage::new(Counting::new(mem));
    let mut p = program(600, 7);
    let mut t = 0;
    s.queue(Job::Save { slot: 2 }).unwrap();
    assert_eq!(s.program_use(), Some(ProgramUse::Reads));
    let (done, steps) = drain(&mut s, &mut p, &mut t);
    assert_eq!(
        done,
        vec![JobDone::Saved {
            slot: 2,
            result: Ok(1)
        }]
    );
    assert_eq!(s.eeprom().inner.busy_violations(), 0);
    let (transfers, polls) = (s.eeprom().transfers, s.eeprom().polls);
    eprintln!("600-line save: {steps} steps, {transfers} transfers, {polls} ready polls");
    // The same bytes as the synchronous save.
    let mut sync = Storage::new(MemEeprom::new());
    sync.save(2, &p).unwrap();
    assert_eq!(s.eeprom().inner.image()[..], sync.eeprom().image()[..]);

    // Load it back, stepped, into an empty program.
    let mut q = Program::default();
    s.queue(Job::Load { slot: 2 }).unwrap();
    assert_eq!(s.program_use(), Some(ProgramUse::Writes));
    let (done, _) = drain(&mut s, &mut q, &mut t);
    assert!(
        matches!(done[..], [JobDone::Loaded { slot: 2, result: Ok(r) }] if r.generation == 1),
        "{done:?}"
    );
    assert_eq!(q, p);
    assert_eq!(s.program_use(), None);
}

#[test]
fn a_write_cycle_that_never_ends_fails_the_job_after_the_limit_and_the_next_job_runs() {
    let mut s = Storage::new(Counting::new(MemEeprom::new()));
    let mut p = program(10, 1);
    let mut t = 0;
    s.eeprom().stuck = true;
    s.queue(Job::Save { slot: 1 }).unwrap();
    // Reads succeed, the first write starts a cycle that never ends.
    let mut failed_at = None;
    for _ in 0..1000 {
        t += 1000;
        if let Some(d) = s.step(Micros(t), &mut p).done {
            assert_eq!(
                d,
                JobDone::Saved {
                    slot: 1,
                    result: Err(StorageError::Eeprom(EepromError::Bus))
                }
            );
            failed_at = Some(t);
            break;
        }
    }
    let failed_at = failed_at.expect("the save fails");
    assert!(!s.busy());
    // The first write was at the step after the two checks of the (erased) copies.
    assert!(failed_at > WRITE_CYCLE_LIMIT_US);
    // The chip answers again: the next job works. The write that never "ended" did land
    // in the RAM model (a 10-line program is one page: copy A of generation 1 is
    // complete), so this save is generation 2.
    s.eeprom().stuck = false;
    s.queue(Job::Save { slot: 1 }).unwrap();
    let (done, _) = drain(&mut s, &mut p, &mut t);
    assert_eq!(
        done,
        vec![JobDone::Saved {
            slot: 1,
            result: Ok(2)
        }]
    );
}

/// The storage side of the run-time I2C recovery: a page write that breaks on
/// the bus is not repeated; the save reports `Eeprom(Bus)` (the LCD shows it, the user
/// saves again), the torn page's write cycle is waited for before any other access, the
/// slot still loads the program saved before, and the next save works.
#[test]
fn a_page_write_broken_on_the_bus_fails_the_save_and_the_next_save_works() {
    let mut mem = MemEeprom::new();
    mem.set_busy_polls(3);
    let mut s = Storage::new(Counting::new(mem));
    let old = program(300, 3);
    let mut p = old.clone();
    let mut t = 0;
    s.queue(Job::Save { slot: 3 }).unwrap();
    let (done, _) = drain(&mut s, &mut p, &mut t);
    assert!(
        matches!(done[..], [JobDone::Saved { result: Ok(1), .. }]),
        "{done:?}"
    );
    let mut p = program(300, 9);
    // A page in the middle of the first copy the second save writes.
    let writes = s.eeprom().writes;
    s.eeprom().break_write = Some(writes + 5);
    s.queue(Job::Save { slot: 3 }).unwrap();
    let (done, _) = drain(&mut s, &mut p, &mut t);
    assert_eq!(
        done,
        vec![JobDone::Saved {
            slot: 3,
            result: Err(StorageError::Eeprom(EepromError::Bus))
        }]
    );
    assert_eq!(
        s.eeprom().writes,
        writes + 6,
        "the broken write was not repeated"
    );
    s.eeprom().break_write = None;
    let mut q = Program::default();
    s.queue(Job::Load { slot: 3 }).unwrap();
    let (done, _) = drain(&mut s, &mut q, &mut t);
    assert!(
        matches!(done[..], [JobDone::Loaded { result: Ok(r), .. }] if r.generation == 1),
        "{done:?}"
    );
    assert_eq!(q, old);
    s.queue(Job::Save { slot: 3 }).unwrap();
    let (done, _) = drain(&mut s, &mut p, &mut t);
    assert!(
        matches!(done[..], [JobDone::Saved { result: Ok(2), .. }]),
        "{done:?}"
    );
    s.queue(Job::Load { slot: 3 }).unwrap();
    let (done, _) = drain(&mut s, &mut q, &mut t);
    assert!(matches!(done[..], [JobDone::Loaded { .. }]), "{done:?}");
    assert_eq!(q, p);
    assert_eq!(s.eeprom().inner.busy_violations(), 0);
}

#[test]
fn jobs_run_in_order_and_boot_record_changes_coalesce() {
    let mut s = Storage::new(Counting::new(MemEeprom::new()));
    let mut p = program(40, 3);
    let mut t = 0;
    s.queue(Job::Save { slot: 3 }).unwrap();
    s.queue(Job::Boot(BootChange::Run {
        slot: Some(3),
        running: true,
    }))
    .unwrap();
    // A STOP before the first boot write ran: only the newest state is written.
    s.queue(Job::Boot(BootChange::Run {
        slot: Some(3),
        running: false,
    }))
    .unwrap();
    let entry = s.fault_entry(4, 65_000);
    s.queue(Job::LogFault(entry)).unwrap();
    s.queue(Job::ClearFaultLog).unwrap();
    s.queue(Job::LogFault(s.fault_entry(6, 1_000))).unwrap();
    assert_eq!(s.jobs().count(), 5);
    let (done, _) = drain(&mut s, &mut p, &mut t);
    let kinds: Vec<String> = done.iter().map(|d| format!("{d:?}")).collect();
    assert!(
        matches!(
            done[0],
            JobDone::Saved {
                slot: 3,
                result: Ok(1)
            }
        ),
        "{kinds:?}"
    );
    assert!(
        matches!(
            done[1],
            JobDone::BootWritten {
                change: BootChange::Run { running: false, .. },
                result: Ok(())
            }
        ),
        "{kinds:?}"
    );
    assert!(matches!(
        done[2],
        JobDone::FaultLogged { result: Ok(()), .. }
    ));
    assert!(matches!(
        done[3],
        JobDone::FaultLogCleared { result: Ok(()) }
    ));
    assert!(matches!(
        done[4],
        JobDone::FaultLogged { result: Ok(()), .. }
    ));
    let mut log = heapless::Vec::new();
    s.fault_log(&mut log).unwrap();
    assert_eq!(log.iter().map(|e| e.code).collect::<Vec<_>>(), vec![6]);
    let rec = s.boot_record().unwrap().unwrap();
    assert_eq!((rec.last_run_slot, rec.run_at_power_up), (Some(3), false));
}

#[test]
fn a_full_queue_refuses_and_synchronous_calls_wait_for_an_empty_one() {
    let mut s = Storage::new(MemEeprom::new());
    for k in 0..QUEUE_JOBS {
        s.queue(Job::LogFault(s.fault_entry(1 + k as u8, 0)))
            .unwrap();
    }
    assert!(s.queue(Job::ClearFaultLog).is_err());
    assert_eq!(s.save(1, &Program::default()), Err(StorageError::Busy));
    let mut p = Program::default();
    let mut t = 0;
    while s.busy() {
        t += 1000;
        let _ = s.step(Micros(t), &mut p);
    }
    assert_eq!(s.save(1, &Program::default()), Ok(1));
}

#[test]
fn a_power_cut_at_any_page_of_a_stepped_save_leaves_old_or_new() {
    let old = program(300, 1);
    let new = program(700, 2);
    let mut base = Storage::new(MemEeprom::new());
    base.save(4, &old).unwrap();
    let start = base.into_eeprom();
    // Bytes of a complete save, then a cut after every 29th byte with a busy chip.
    let total = {
        let mut s = Storage::new(start.clone());
        let b = s.eeprom().bytes_written();
        s.save(4, &new).unwrap();
        s.eeprom().bytes_written() - b
    };
    let mut seen_new = false;
    for cut in (0..=total).step_by(29).chain([total]) {
        let mut e = start.clone();
        e.set_busy_polls(2);
        e.cut_power_after(cut);
        let mut s = Storage::new(e);
        let mut p = new.clone();
        s.queue(Job::Save { slot: 4 }).unwrap();
        let mut t = 0;
        let mut result = None;
        while s.busy() {
            t += 1000;
            if let Some(d) = s.step(Micros(t), &mut p).done {
                result = Some(d);
            }
        }
        let ok = matches!(result, Some(JobDone::Saved { result: Ok(_), .. }));
        assert_eq!(ok, cut == total, "cut {cut}: {result:?}");
        let mut e = s.into_eeprom();
        e.restore_power();
        e.set_busy_polls(0);
        let mut s = Storage::new(e);
        let mut got = Program::default();
        s.load(4, &mut got).unwrap();
        if got == new {
            seen_new = true;
        } else {
            assert_eq!(got, old, "cut {cut}: neither old nor new");
            assert!(!seen_new, "old again after new at {cut}");
        }
    }
    assert!(seen_new);
}

#[test]
fn power_up_waits_for_a_write_cycle_left_running_by_a_reset() {
    let mut s = Storage::new(MemEeprom::new());
    s.save(1, &program(20, 5)).unwrap();
    s.set_run_state(Some(1), true).unwrap();
    let mut e = s.into_eeprom();
    // A reset right after a write: the chip is still busy for a while.
    e.set_busy_polls(4);
    e.start_write((EEPROM_BYTES - PAGE_BYTES) as u16, &[0; 4])
        .unwrap();
    let mut s = Storage::new(e);
    let mut p = Program::default();
    let up = s.power_up(&mut p).unwrap();
    assert!(up.run);
    assert_eq!(p, program(20, 5));
    assert_eq!(s.eeprom().busy_violations(), 0);
}

#[test]
fn the_write_cycle_limit_counts_from_the_first_poll_not_from_the_slow_write_step() {
    // On the board a step's time is taken before its transfer, and a page write takes
    // about 7 ms at 100 kHz: the next step comes about 8 ms later, and the chip is then
    // still busy for up to 5 ms. That must not count against the 10 ms limit.
    let mut mem = MemEeprom::new();
    mem.set_busy_polls(5);
    let mut s = Storage::new(Counting::new(mem));
    let mut p = program(200, 9);
    s.queue(Job::Save { slot: 1 }).unwrap();
    let mut t = 0u64;
    let mut done = None;
    while s.busy() {
        let written = s.eeprom().inner.pages_written();
        let step = s.step(Micros(t), &mut p);
        t += if s.eeprom().inner.pages_written() > written {
            8_000
        } else {
            1_000
        };
        if let Some(d) = step.done {
            done = Some(d);
        }
    }
    assert_eq!(
        done,
        Some(JobDone::Saved {
            slot: 1,
            result: Ok(1)
        })
    );
}
