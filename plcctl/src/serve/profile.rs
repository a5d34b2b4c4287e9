//! The application profile of `serve --profile` and `faults --profile` (service.md 13):
//! names for the PLC's variables, the lift mimic's roles, state texts with their banner
//! level, the application counters' names, and for the fault log the texts of the
//! application faults and the names of its two values. Every error names its key (exit 1).

use std::collections::BTreeMap;
use std::path::Path;

use serde::Serialize;
use shared_protocol::service::MAX_SUBSCRIBED_Q;
use toml::{Table, Value};

use crate::fail::{Fail, Result};

/// A variable the page can show.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Operand {
    D(u8),
    O(u8),
    A(u8),
    Q(u8),
    Lcd(u8),
}

impl Operand {
    /// `D00`-`D15`, `O00`-`O07`, `A00`-`A03`, `Q00`-`Q63`, `lcd0`-`lcd3`.
    pub fn parse(s: &str) -> Option<Operand> {
        if let Some(n) = s.strip_prefix("lcd") {
            return match n {
                "0" | "1" | "2" | "3" => n.parse().ok().map(Operand::Lcd),
                _ => None,
            };
        }
        let (kind, digits) = s.split_at_checked(1)?;
        if digits.len() != 2 || !digits.bytes().all(|b| b.is_ascii_digit()) {
            return None;
        }
        let n: u8 = digits.parse().ok()?;
        match kind {
            "D" if n < 16 => Some(Operand::D(n)),
            "O" if n < 8 => Some(Operand::O(n)),
            "A" if n < 4 => Some(Operand::A(n)),
            "Q" if n < 64 => Some(Operand::Q(n)),
            _ => None,
        }
    }

    /// The canonical name, also the trend's column name where there is one.
    pub fn name(self) -> String {
        match self {
            Operand::D(n) => format!("D{n:02}"),
            Operand::O(n) => format!("O{n:02}"),
            Operand::A(n) => format!("A{n:02}"),
            Operand::Q(n) => format!("Q{n:02}"),
            Operand::Lcd(n) => format!("lcd{n}"),
        }
    }
}

impl Serialize for Operand {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.serialize_str(&self.name())
    }
}

/// A state's banner level.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Level {
    Ok,
    Warning,
    Fault,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StateText {
    pub text: String,
    pub level: Level,
}

/// `[lift]`: the mimic's geometry and door.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Lift {
    pub floors: u8,
    pub door_stroke_s: f64,
    pub door_fault_states: Vec<i64>,
    pub call_buttons: Vec<Operand>,
    /// D inputs that are all on only while the car is level at a floor (the vanes); the
    /// mimic draws the car between floors when it stands with one of them off (a trip
    /// mid-shaft). Empty: level whenever it is not moving.
    pub level_inputs: Vec<Operand>,
    /// `[lift.car_panel]`: the car's panel elements the lift has, each a D or O bit
    /// ([`CAR_PANEL`]); the floor buttons are `call_buttons`, the floor display the
    /// `floor` variable.
    pub car_panel: BTreeMap<String, Operand>,
}

/// The car panel's elements besides the floor buttons and the floor display (004 §2.7.1:
/// the alarm for a passenger trapped in the car, the door-open button, the priority
/// key; and the in-car STOP a lift may have), each shown lit while its bit is 1.
pub const CAR_PANEL: [&str; 5] = ["alarm", "alarm_bell", "door_open", "priority_key", "stop"];

/// A parsed profile (sent to the page as JSON).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Profile {
    pub name: String,
    /// `"lift"` or `"table"`.
    pub kind: String,
    /// Name → variable, in the file's order of names (sorted).
    pub vars: BTreeMap<String, Operand>,
    pub lift: Option<Lift>,
    pub states: BTreeMap<i64, StateText>,
    /// Name → `Q60`-`Q63`.
    pub counters: BTreeMap<String, Operand>,
    /// `[faults]`: application fault n (1-99: `ALM K00 00nn`, fault-log code 100 + n) →
    /// its text.
    pub faults: BTreeMap<u8, String>,
    /// `[log] values`: the names of a log entry's two application values (the program's
    /// first two `LCD` fields; default `lcd0`, `lcd1`).
    pub log_values: [String; 2],
}

/// The roles the lift mimic needs in `[vars]`.
pub const LIFT_ROLES: [&str; 8] = [
    "floor",
    "target",
    "state",
    "load",
    "door_open_cmd",
    "door_closed",
    "up",
    "down",
];

impl Default for Profile {
    /// Without `--profile`: a table without names.
    fn default() -> Self {
        Profile {
            name: String::new(),
            kind: "table".into(),
            vars: BTreeMap::new(),
            lift: None,
            states: BTreeMap::new(),
            counters: BTreeMap::new(),
            faults: BTreeMap::new(),
            log_values: ["lcd0".into(), "lcd1".into()],
        }
    }
}

fn err(file: &str, key: &str, msg: impl std::fmt::Display) -> Fail {
    Fail::Usage(anyhow::anyhow!("{file}: {key}: {msg}"))
}

impl Profile {
    pub fn load(path: &Path) -> Result<Profile> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| Fail::Usage(anyhow::anyhow!("cannot read {}: {e}", path.display())))?;
        Profile::parse(&text, &path.display().to_string())
    }

    /// Parses `text` (named `file` in errors).
    pub fn parse(text: &str, file: &str) -> Result<Profile> {
        let t: Table = text
            .parse()
            .map_err(|e: toml::de::Error| Fail::Usage(anyhow::anyhow!("{file}: {e}")))?;
        let mut p = Profile::default();
        for (key, v) in &t {
            match key.as_str() {
                "name" => p.name = string(file, "name", v)?,
                "kind" => {
                    p.kind = string(file, "kind", v)?;
                    if p.kind != "lift" && p.kind != "table" {
                        return Err(err(file, "kind", "must be \"lift\" or \"table\""));
                    }
                }
                "vars" => {
                    for (name, v) in table(file, "vars", v)? {
                        let k = format!("vars.{name}");
                        p.vars.insert(name.clone(), operand(file, &k, v)?);
                    }
                }
                "lift" => p.lift = Some(lift(file, table(file, "lift", v)?)?),
                "states" => {
                    for (code, v) in table(file, "states", v)? {
                        let k = format!("states.{code}");
                        let n: i64 = code
                            .parse()
                            .map_err(|_| err(file, &k, "a state is an integer value"))?;
                        p.states.insert(n, state(file, &k, v)?);
                    }
                }
                "counters" => {
                    for (name, v) in table(file, "counters", v)? {
                        let k = format!("counters.{name}");
                        let o = operand(file, &k, v)?;
                        if !matches!(o, Operand::Q(60..=63)) {
                            return Err(err(file, &k, "application counters are Q60-Q63"));
                        }
                        p.counters.insert(name.clone(), o);
                    }
                }
                "faults" => {
                    for (n, v) in table(file, "faults", v)? {
                        let k = format!("faults.{n}");
                        let n: u8 = n
                            .parse()
                            .ok()
                            .filter(|n| (1..=99).contains(n))
                            .ok_or_else(|| err(file, &k, "an application fault is 1-99"))?;
                        p.faults.insert(n, string(file, &k, v)?);
                    }
                }
                "log" => {
                    for (k, v) in table(file, "log", v)? {
                        let kk = format!("log.{k}");
                        match k.as_str() {
                            "values" => {
                                let names = v
                                    .as_array()
                                    .and_then(|a| {
                                        a.iter()
                                            .map(|x| x.as_str().map(String::from))
                                            .collect::<Option<Vec<_>>>()
                                    })
                                    .and_then(|v| <[String; 2]>::try_from(v).ok())
                                    .ok_or_else(|| err(file, &kk, "must be two names"))?;
                                p.log_values = names;
                            }
                            _ => return Err(err(file, &kk, "unknown key")),
                        }
                    }
                }
                other => return Err(err(file, other, "unknown key")),
            }
        }
        let q = p.subscribed_q();
        if q.len() > MAX_SUBSCRIBED_Q {
            return Err(err(
                file,
                "vars",
                format!("at most {MAX_SUBSCRIBED_Q} Q variables, not {}", q.len()),
            ));
        }
        if p.kind == "lift" {
            if p.lift.is_none() {
                return Err(err(
                    file,
                    "lift",
                    "missing ([lift] is needed for kind = \"lift\")",
                ));
            }
            if let Some(role) = LIFT_ROLES.iter().find(|r| !p.vars.contains_key(**r)) {
                return Err(err(
                    file,
                    &format!("vars.{role}"),
                    "missing (kind = \"lift\")",
                ));
            }
        }
        Ok(p)
    }

    /// The Q variables to subscribe: the profile's, else Q00-Q07.
    pub fn subscribed_q(&self) -> Vec<u8> {
        let mut q: Vec<u8> = self
            .vars
            .values()
            .filter_map(|o| match o {
                Operand::Q(n) => Some(*n),
                _ => None,
            })
            .collect();
        q.sort_unstable();
        q.dedup();
        if q.is_empty() {
            q = (0..8).collect();
        }
        q
    }
}

fn string(file: &str, key: &str, v: &Value) -> Result<String> {
    v.as_str()
        .map(String::from)
        .ok_or_else(|| err(file, key, "must be a string"))
}

fn table<'a>(file: &str, key: &str, v: &'a Value) -> Result<&'a Table> {
    v.as_table()
        .ok_or_else(|| err(file, key, "must be a table"))
}

fn operand(file: &str, key: &str, v: &Value) -> Result<Operand> {
    let s = string(file, key, v)?;
    Operand::parse(&s).ok_or_else(|| {
        err(
            file,
            key,
            format!("{s:?} is not a variable (D00-D15, O00-O07, A00-A03, Q00-Q63, lcd0-lcd3)"),
        )
    })
}

fn state(file: &str, key: &str, v: &Value) -> Result<StateText> {
    let t = table(file, key, v)?;
    let mut text = None;
    let mut level = None;
    for (k, v) in t {
        let kk = format!("{key}.{k}");
        match k.as_str() {
            "text" => text = Some(string(file, &kk, v)?),
            "level" => {
                level = Some(match string(file, &kk, v)?.as_str() {
                    "ok" => Level::Ok,
                    "warning" => Level::Warning,
                    "fault" => Level::Fault,
                    _ => return Err(err(file, &kk, "must be \"ok\", \"warning\" or \"fault\"")),
                })
            }
            _ => return Err(err(file, &kk, "unknown key")),
        }
    }
    Ok(StateText {
        text: text.ok_or_else(|| err(file, &format!("{key}.text"), "missing"))?,
        level: level.unwrap_or(Level::Ok),
    })
}

fn lift(file: &str, t: &Table) -> Result<Lift> {
    let mut l = Lift {
        floors: 0,
        door_stroke_s: 2.0,
        door_fault_states: Vec::new(),
        call_buttons: Vec::new(),
        level_inputs: Vec::new(),
        car_panel: BTreeMap::new(),
    };
    for (k, v) in t {
        let kk = format!("lift.{k}");
        match k.as_str() {
            "floors" => {
                l.floors = v
                    .as_integer()
                    .and_then(|n| u8::try_from(n).ok())
                    .filter(|n| (2..=8).contains(n))
                    .ok_or_else(|| err(file, &kk, "must be an integer 2-8"))?
            }
            "door_stroke_s" => {
                l.door_stroke_s = v
                    .as_float()
                    .or_else(|| v.as_integer().map(|n| n as f64))
                    .filter(|s| (0.0..=60.0).contains(s))
                    .ok_or_else(|| err(file, &kk, "must be seconds, 0-60"))?
            }
            "door_fault_states" => {
                l.door_fault_states = v
                    .as_array()
                    .and_then(|a| a.iter().map(Value::as_integer).collect::<Option<Vec<_>>>())
                    .ok_or_else(|| err(file, &kk, "must be a list of integers"))?
            }
            "call_buttons" => l.call_buttons = d_inputs(file, &kk, v, "a call button")?,
            "level_inputs" => l.level_inputs = d_inputs(file, &kk, v, "a level input")?,
            "car_panel" => l.car_panel = car_panel(file, &kk, v)?,
            _ => return Err(err(file, &kk, "unknown key")),
        }
    }
    if l.floors == 0 {
        return Err(err(file, "lift.floors", "missing"));
    }
    Ok(l)
}

/// `[lift.car_panel]`: element name → a D input or an O output.
fn car_panel(file: &str, key: &str, v: &Value) -> Result<BTreeMap<String, Operand>> {
    let mut out = BTreeMap::new();
    for (name, v) in table(file, key, v)? {
        let k = format!("{key}.{name}");
        if !CAR_PANEL.contains(&name.as_str()) {
            let known = CAR_PANEL.join(", ");
            return Err(err(file, &k, format!("unknown key (one of {known})")));
        }
        let o = operand(file, &k, v)?;
        if !matches!(o, Operand::D(_) | Operand::O(_)) {
            return Err(err(file, &k, "a panel element is a D input or an O output"));
        }
        out.insert(name.clone(), o);
    }
    Ok(out)
}

/// A list of D inputs (`what` names one in the error).
fn d_inputs(file: &str, key: &str, v: &Value, what: &str) -> Result<Vec<Operand>> {
    let a = v
        .as_array()
        .ok_or_else(|| err(file, key, "must be a list of D inputs"))?;
    let mut out = Vec::new();
    for (i, b) in a.iter().enumerate() {
        let o = operand(file, &format!("{key}[{i}]"), b)?;
        if !matches!(o, Operand::D(_)) {
            return Err(err(
                file,
                &format!("{key}[{i}]"),
                format!("{what} is a D input"),
            ));
        }
        out.push(o);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIFT: &str = include_str!("../../../shared-protocol/programs/lift.profile.toml");
    const MOTOR: &str = include_str!("../../../shared-protocol/programs/motor.profile.toml");
    const LIFT_PLC: &str = include_str!("../../../shared-protocol/programs/lift.plc");

    fn error(text: &str) -> String {
        Profile::parse(text, "p.toml").unwrap_err().to_string()
    }

    #[test]
    fn the_lift_profile_matches_lift_plc() {
        let p = Profile::parse(LIFT, "lift.profile.toml").unwrap();
        assert_eq!(p.kind, "lift");
        assert_eq!(p.vars["floor"], Operand::Q(4));
        assert_eq!(p.vars["state"], Operand::Q(7));
        assert_eq!(p.subscribed_q(), [2, 4, 5, 6, 7, 8]);
        // Every state code lift.plc writes to Q07 has a text (lift.md 3.6), and no other.
        let mut written: Vec<i64> = Vec::new();
        let lines: Vec<&str> = LIFT_PLC.lines().collect();
        for (i, l) in lines.iter().enumerate() {
            if l.contains("WR  Q07") {
                let prev = lines[i - 1];
                if let Some(k) = prev.split("K00 ").nth(1) {
                    written.push(k.split_whitespace().next().unwrap().parse().unwrap());
                }
            }
        }
        written.sort_unstable();
        written.dedup();
        let mut listed: Vec<i64> = p.states.keys().copied().filter(|k| *k != 0).collect();
        listed.sort_unstable();
        assert_eq!(written, listed);
        let l = p.lift.unwrap();
        assert_eq!(l.floors, 4);
        assert_eq!(l.door_fault_states, [10]);
        assert_eq!(l.level_inputs, [Operand::D(10), Operand::D(11)]);
        // The car panel: what lift.plc has (lift.md 3.2: the in-car bell D14 ringing
        // O06, the in-car STOP D13); no door-open button and no priority key.
        let panel: Vec<(&str, Operand)> =
            l.car_panel.iter().map(|(k, o)| (k.as_str(), *o)).collect();
        assert_eq!(
            panel,
            [
                ("alarm", Operand::D(14)),
                ("alarm_bell", Operand::O(6)),
                ("stop", Operand::D(13))
            ]
        );
        for (role, o) in [
            ("in-car bell", "D14"),
            ("alarm bell", "O06"),
            ("in-car STOP", "D13"),
        ] {
            assert_eq!(p.vars[role].name(), o, "{role}");
        }
        assert_eq!(p.counters.len(), 4);
        assert_eq!(p.states[&12].level, Level::Fault);
        assert_eq!(p.states[&7].level, Level::Warning);
    }

    /// Every application fault lift.plc logs (`ALM K00 00nn`) has a text, and no other;
    /// the log's values are named as the variables lift.plc shows in its first two
    /// `LCD` fields (floor and target, lift.md 3.3).
    #[test]
    fn the_lift_profile_names_what_lift_plc_logs() {
        let p = Profile::parse(LIFT, "lift.profile.toml").unwrap();
        let mut alarms: Vec<u8> = Vec::new();
        let mut lcd: Vec<String> = Vec::new();
        let mut last_load = String::new();
        for l in LIFT_PLC.lines() {
            // `NNN MNEMONIC [OPERAND [CONSTANT]]`, then a comment.
            let f: Vec<&str> = l.split(';').next().unwrap().split_whitespace().collect();
            match f.get(1).copied() {
                Some("ALM") => alarms.push(f[3].parse().unwrap()),
                Some("LD") => last_load = f[2].to_string(),
                Some("LCD") => lcd.push(last_load.clone()),
                _ => {}
            }
        }
        assert_eq!(alarms, [10, 11, 12, 13, 14, 15]);
        assert_eq!(p.faults.keys().copied().collect::<Vec<_>>(), alarms);
        // The same words as the states of those codes (lift.md 3.6).
        for (n, text) in &p.faults {
            assert_eq!(text, &p.states[&i64::from(*n)].text, "fault {n}");
        }
        assert_eq!(p.log_values, ["floor", "target"]);
        for (k, name) in p.log_values.iter().enumerate() {
            assert_eq!(p.vars[name].name(), lcd[k], "value {k} = lcd{k}");
        }
    }

    #[test]
    fn the_motor_profile_is_a_table() {
        let p = Profile::parse(MOTOR, "motor.profile.toml").unwrap();
        assert_eq!(p.kind, "table");
        assert_eq!(p.subscribed_q(), [0, 2]);
        assert_eq!(p.vars["speed pot"], Operand::A(1));
    }

    #[test]
    fn errors_name_the_key() {
        assert!(error("colour = 1").contains("p.toml: colour: unknown key"));
        assert!(error("[vars]\nfloor = \"Q64\"").contains("vars.floor: \"Q64\" is not a variable"));
        assert!(error("[vars]\nx = \"D16\"").contains("vars.x"));
        assert!(error("[vars]\nx = \"lcd01\"").contains("vars.x"));
        assert!(error("kind = \"graph\"").contains("kind: must be"));
        assert!(error("[lift]\nfloors = 9").contains("lift.floors"));
        assert!(error("[lift]\nfloors = 4\nspeed = 1").contains("lift.speed: unknown key"));
        assert!(
            error("[lift]\nfloors = 4\ncall_buttons = [\"O00\"]").contains("lift.call_buttons[0]")
        );
        assert!(
            error("[lift]\nfloors = 4\n[lift.car_panel]\nhorn = \"D14\"")
                .contains("lift.car_panel.horn: unknown key (one of alarm, ")
        );
        assert!(
            error("[lift]\nfloors = 4\n[lift.car_panel]\nalarm = \"Q04\"")
                .contains("lift.car_panel.alarm: a panel element is a D input or an O output")
        );
        assert!(
            error("[lift]\nfloors = 4\n[lift.car_panel]\nstop = \"D16\"")
                .contains("lift.car_panel.stop: \"D16\" is not a variable")
        );
        assert!(error("[states]\nx = { text = \"a\" }").contains("states.x"));
        assert!(error("[states]\n3 = { text = \"a\", level = \"bad\" }").contains("states.3.level"));
        assert!(error("[states]\n3 = { level = \"ok\" }").contains("states.3.text: missing"));
        assert!(error("[counters]\na = \"Q10\"").contains("counters.a: application counters"));
        let nine: String = (0..9).map(|n| format!("v{n} = \"Q{n:02}\"\n")).collect();
        assert!(error(&format!("[vars]\n{nine}")).contains("vars: at most 8 Q"));
        assert!(error("kind = \"lift\"\n[lift]\nfloors = 4").contains("vars.floor: missing"));
        assert!(error("kind = \"lift\"").contains("lift: missing"));
        assert!(error("name = ").contains("p.toml"));
        assert!(error("[faults]\n100 = \"x\"").contains("faults.100: an application fault"));
        assert!(error("[faults]\n1 = 2").contains("faults.1: must be a string"));
        assert!(error("[log]\nvalues = [\"a\"]").contains("log.values: must be two names"));
        assert!(error("[log]\nx = 1").contains("log.x: unknown key"));
    }

    #[test]
    fn without_a_profile_the_page_is_a_table_of_q00_to_q07() {
        let p = Profile::default();
        assert_eq!(p.kind, "table");
        assert_eq!(p.subscribed_q(), (0..8).collect::<Vec<u8>>());
    }
}
