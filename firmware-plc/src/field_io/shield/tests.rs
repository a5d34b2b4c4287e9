use std::collections::VecDeque;

use super::*;
use crate::field_io::clt01::InputFrame;
use crate::field_io::vni8200::Status;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Ev {
    Read,
    Cmd(u16),
    OutEn(bool),
}

/// The bus as the chips answer it: queued frames first, then the healthy ones.
struct Bus {
    inputs: u8,
    input_frames: VecDeque<u16>,
    answers: VecDeque<u16>,
    log: Vec<Ev>,
}

fn healthy_answer() -> u16 {
    vni8200::encode_answer(Status {
        fb_ok: true,
        ..Default::default()
    })
}

impl Bus {
    fn new(inputs: u8) -> Self {
        Bus {
            inputs,
            input_frames: VecDeque::new(),
            answers: VecDeque::new(),
            log: Vec::new(),
        }
    }
    fn clear(&mut self) {
        self.log.clear();
    }
}

impl SpiPort for Bus {
    fn exchange_inputs(&mut self) -> u16 {
        self.log.push(Ev::Read);
        self.input_frames
            .pop_front()
            .unwrap_or(clt01::encode(InputFrame {
                inputs: self.inputs,
                ..Default::default()
            }))
    }
    fn exchange_outputs(&mut self, command: u16) -> u16 {
        self.log.push(Ev::Cmd(command));
        self.answers.pop_front().unwrap_or(healthy_answer())
    }
    fn set_out_enable(&mut self, on: bool) {
        self.log.push(Ev::OutEn(on));
    }
}

fn tripped_events() -> Vec<Ev> {
    vec![Ev::OutEn(false), Ev::Cmd(vni8200::command(0))]
}

#[test]
fn inputs_and_outputs_pass_through_a_healthy_shield() {
    let mut s = Shield::new();
    let mut bus = Bus::new(0xA5);
    assert_eq!(s.read_inputs(&mut bus), 0xA5);
    s.write_outputs(0x81, &mut bus);
    assert_eq!(
        bus.log,
        vec![Ev::Read, Ev::Cmd(vni8200::command(0x81)), Ev::OutEn(true)]
    );
    assert_eq!(s.take_trip(), None);
}

#[test]
fn an_all_off_image_drops_out_en_before_the_command() {
    let mut s = Shield::new();
    let mut bus = Bus::new(0);
    s.write_outputs(0, &mut bus);
    assert_eq!(
        bus.log,
        vec![Ev::OutEn(false), Ev::Cmd(vni8200::command(0))]
    );
}

#[test]
fn one_bad_input_frame_is_read_again_and_never_used() {
    let mut s = Shield::new();
    let mut bus = Bus::new(0x0F);
    // A frame with IN8 flipped: its check fails.
    let bad = clt01::encode(InputFrame {
        inputs: 0x0F,
        ..Default::default()
    }) ^ 0x8000;
    bus.input_frames.push_back(bad);
    assert_eq!(s.read_inputs(&mut bus), 0x0F);
    assert_eq!(bus.log, vec![Ev::Read, Ev::Read]);
    assert_eq!(s.take_trip(), None);
}

#[test]
fn two_bad_input_frames_trip_with_the_outputs_off_first() {
    let mut s = Shield::new();
    let mut bus = Bus::new(0xFF);
    bus.input_frames.extend([0xFFFF, 0x0000]);
    assert_eq!(s.read_inputs(&mut bus), 0);
    let mut want = vec![Ev::Read, Ev::Read];
    want.extend(tripped_events());
    assert_eq!(bus.log, want);
    assert_eq!(s.take_trip(), Some(FieldFault::FrameCheck));
    assert_eq!(s.take_trip(), None, "reported once");
    assert_eq!(FieldFault::FrameCheck.code(), 203);
}

#[test]
fn input_alarms_trip_with_their_own_faults() {
    for (frame, fault) in [
        (
            InputFrame {
                inputs: 1,
                under_voltage: true,
                over_temperature: false,
            },
            FieldFault::SupplyLost,
        ),
        (
            InputFrame {
                inputs: 1,
                under_voltage: false,
                over_temperature: true,
            },
            FieldFault::InputOvertemp,
        ),
    ] {
        let mut s = Shield::new();
        let mut bus = Bus::new(1);
        bus.input_frames.push_back(clt01::encode(frame));
        assert_eq!(s.read_inputs(&mut bus), 0);
        assert_eq!(s.take_trip(), Some(fault));
    }
}

#[test]
fn a_channel_in_overtemperature_turns_every_output_off() {
    let mut s = Shield::new();
    let mut bus = Bus::new(0);
    bus.answers.push_back(vni8200::encode_answer(Status {
        channel_overtemp: 0x04,
        fb_ok: true,
        ..Default::default()
    }));
    s.write_outputs(0x04, &mut bus);
    let mut want = vec![Ev::Cmd(vni8200::command(0x04))];
    want.extend(tripped_events());
    assert_eq!(bus.log, want, "OUT_EN never went high");
    assert_eq!(s.take_trip(), Some(FieldFault::OutputOvertemp));
    assert_eq!(FieldFault::OutputOvertemp.code(), 200);
    // Latched: the next writes keep OUT_EN low and send the all-off command, the inputs
    // read 0 without a frame.
    bus.clear();
    s.write_outputs(0x04, &mut bus);
    assert_eq!(s.read_inputs(&mut bus), 0);
    assert_eq!(bus.log, tripped_events());
    // RUN again: the next write checks again and enables the outputs.
    s.rearm();
    bus.clear();
    s.write_outputs(0x04, &mut bus);
    assert_eq!(
        bus.log,
        vec![Ev::Cmd(vni8200::command(0x04)), Ev::OutEn(true)]
    );
}

#[test]
fn the_case_warning_trips_as_an_overtemperature() {
    let mut s = Shield::new();
    let mut bus = Bus::new(0);
    bus.answers.push_back(vni8200::encode_answer(Status {
        temp_warning: true,
        fb_ok: true,
        ..Default::default()
    }));
    s.write_outputs(1, &mut bus);
    assert_eq!(s.take_trip(), Some(FieldFault::OutputOvertemp));
}

#[test]
fn power_good_lost_trips_as_a_supply_loss() {
    let mut s = Shield::new();
    let mut bus = Bus::new(0);
    bus.answers.push_back(vni8200::encode_answer(Status {
        power_fault: true,
        fb_ok: true,
        ..Default::default()
    }));
    s.write_outputs(1, &mut bus);
    assert_eq!(s.take_trip(), Some(FieldFault::SupplyLost));
    assert_eq!(FieldFault::SupplyLost.code(), 201);
}

#[test]
fn fb_ok_low_is_allowed_only_while_the_dc_dc_starts() {
    let mut s = Shield::new();
    let mut bus = Bus::new(0);
    let low = vni8200::encode_answer(Status::default());
    for _ in 0..FB_OK_GRACE_EXCHANGES {
        bus.answers.push_back(low);
        s.write_outputs(1, &mut bus);
        assert_eq!(s.take_trip(), None);
    }
    bus.answers.push_back(low);
    s.write_outputs(1, &mut bus);
    assert_eq!(s.take_trip(), Some(FieldFault::SupplyLost));
}

#[test]
fn a_refused_command_is_sent_again_once_then_trips() {
    let refused = vni8200::encode_answer(Status {
        parity_failed: true,
        fb_ok: true,
        ..Default::default()
    });
    let mut s = Shield::new();
    let mut bus = Bus::new(0);
    bus.answers.push_back(refused);
    s.write_outputs(3, &mut bus);
    assert_eq!(
        bus.log,
        vec![
            Ev::Cmd(vni8200::command(3)),
            Ev::Cmd(vni8200::command(3)),
            Ev::OutEn(true)
        ]
    );
    assert_eq!(s.take_trip(), None);
    bus.answers.extend([refused, 0xFFFF]);
    s.write_outputs(3, &mut bus);
    assert_eq!(s.take_trip(), Some(FieldFault::FrameCheck));
}
