//! deckwatch's own messages as JSON, with a JSON Schema: what Foxglove/Lichtblick plot, what the
//! Python `mcap` reader gets, and what deckwatch reads back exactly.
//!
//! Every field is written, by name, as the message holds it: integers as integers, finite floats
//! as the shortest decimal that reads back to the same bits (`serde_json` with
//! `float_roundtrip`), NaN as `null` and infinities as `"inf"`/`"-inf"` (JSON has neither),
//! enums by their variant's name (a code that is no variant: its number), booleans as booleans
//! (a byte that is neither: its number). Reading a message back gives the same value, field for
//! field, NaN as NaN: re-simulation compares recorded and recomputed messages with it.

use deckwatch_common::camera::{CameraModel, Distortion};
use deckwatch_common::deck::DeckLayout;
use deckwatch_common::ellipse::Ellipse;
use deckwatch_common::markers::{Marker, MarkerSet, RejectCounts};
use deckwatch_common::messages::{
    AlternativeAttitude, AttitudeMessage, DropCounts, FrameContext, FrameHeader, FrameStamp, LandingDecision,
    LinkTraffic, MarkerMessage, StageTimes, Truth, VehicleAttitude, VehicleSample,
};
use deckwatch_common::rotation::{Euler313, Quaternion, Rpy};
use deckwatch_common::wire::{WireBool, WireCode, WireEnum};
use serde_json::{json, Map, Value};

/// A field that does not read as its type: where (dotted path) and what was wrong.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{path}: {problem}")]
pub struct FieldError {
    pub path: String,
    pub problem: String,
}

impl FieldError {
    fn expected(what: &str, got: &Value) -> Self {
        let mut shown = got.to_string();
        if shown.len() > 40 {
            shown.truncate(40);
            shown.push_str("...");
        }
        Self {
            path: String::new(),
            problem: format!("expected {what}, got {shown}"),
        }
    }

    fn within(mut self, parent: &str) -> Self {
        self.path = if self.path.is_empty() {
            parent.to_string()
        } else {
            format!("{parent}.{}", self.path)
        };
        self
    }
}

/// A value written to and read from a recording's JSON, with its JSON Schema.
pub trait JsonField: Sized {
    fn to_json(&self) -> Value;
    fn from_json(v: &Value) -> Result<Self, FieldError>;
    fn json_schema() -> Value;
}

impl JsonField for f64 {
    fn to_json(&self) -> Value {
        match serde_json::Number::from_f64(*self) {
            Some(n) => Value::Number(n),
            None if self.is_nan() => Value::Null,
            None if *self > 0.0 => Value::String("inf".into()),
            None => Value::String("-inf".into()),
        }
    }

    fn from_json(v: &Value) -> Result<Self, FieldError> {
        match v {
            Value::Number(n) => n.as_f64().ok_or_else(|| FieldError::expected("a number", v)),
            Value::Null => Ok(f64::NAN),
            Value::String(s) if s == "inf" => Ok(f64::INFINITY),
            Value::String(s) if s == "-inf" => Ok(f64::NEG_INFINITY),
            _ => Err(FieldError::expected(
                "a number, null (NaN), \"inf\" or \"-inf\"",
                v,
            )),
        }
    }

    fn json_schema() -> Value {
        json!({"type": ["number", "null", "string"]})
    }
}

macro_rules! json_integer {
    ($($ty:ty),+) => {$(
        impl JsonField for $ty {
            fn to_json(&self) -> Value {
                json!(*self)
            }

            fn from_json(v: &Value) -> Result<Self, FieldError> {
                let n = match v {
                    Value::Number(n) if n.is_u64() => n.as_u64().and_then(|n| <$ty>::try_from(n).ok()),
                    Value::Number(n) if n.is_i64() => n.as_i64().and_then(|n| <$ty>::try_from(n).ok()),
                    _ => None,
                };
                n.ok_or_else(|| FieldError::expected(concat!("an integer (", stringify!($ty), ")"), v))
            }

            fn json_schema() -> Value {
                json!({"type": "integer"})
            }
        }
    )+};
}

json_integer!(u64, u32, i64, usize);

impl JsonField for WireBool {
    fn to_json(&self) -> Value {
        match self.try_get() {
            Ok(b) => Value::Bool(b),
            Err(_) => json!(self.byte()),
        }
    }

    fn from_json(v: &Value) -> Result<Self, FieldError> {
        match v {
            Value::Bool(b) => Ok((*b).into()),
            Value::Number(n) => n
                .as_u64()
                .and_then(|n| u8::try_from(n).ok())
                .map(WireBool::from_byte)
                .ok_or_else(|| FieldError::expected("a boolean or a byte", v)),
            _ => Err(FieldError::expected("a boolean", v)),
        }
    }

    fn json_schema() -> Value {
        json!({"type": ["boolean", "integer"]})
    }
}

impl<E: WireEnum> JsonField for WireCode<E> {
    fn to_json(&self) -> Value {
        match self.try_get() {
            Ok(e) => Value::String(e.variant_name().into()),
            Err(_) => json!(self.code()),
        }
    }

    fn from_json(v: &Value) -> Result<Self, FieldError> {
        match v {
            Value::String(s) => E::VARIANTS
                .iter()
                .find(|e| e.variant_name() == s)
                .map(|&e| e.into())
                .ok_or_else(|| FieldError::expected(&format!("a {} variant", E::NAME), v)),
            Value::Number(n) => n
                .as_u64()
                .and_then(|n| u32::try_from(n).ok())
                .map(WireCode::from_code)
                .ok_or_else(|| FieldError::expected("a variant name or a u32 code", v)),
            _ => Err(FieldError::expected(&format!("a {} variant", E::NAME), v)),
        }
    }

    fn json_schema() -> Value {
        let names: Vec<&str> = E::VARIANTS.iter().map(|e| e.variant_name()).collect();
        json!({"type": ["string", "integer"], "description": format!("{}: {}", E::NAME, names.join(", "))})
    }
}

impl<T: JsonField, const N: usize> JsonField for [T; N] {
    fn to_json(&self) -> Value {
        Value::Array(self.iter().map(JsonField::to_json).collect())
    }

    fn from_json(v: &Value) -> Result<Self, FieldError> {
        let items = v
            .as_array()
            .filter(|a| a.len() == N)
            .ok_or_else(|| FieldError::expected(&format!("an array of {N}"), v))?;
        let mut out = Vec::with_capacity(N);
        for (i, item) in items.iter().enumerate() {
            out.push(T::from_json(item).map_err(|e| e.within(&i.to_string()))?);
        }
        out.try_into()
            .map_err(|_| FieldError::expected(&format!("an array of {N}"), v))
    }

    fn json_schema() -> Value {
        json!({"type": "array", "items": T::json_schema(), "minItems": N, "maxItems": N})
    }
}

/// The field `name` of an object, read as `T`.
pub fn field<T: JsonField>(object: &Map<String, Value>, name: &str) -> Result<T, FieldError> {
    let v = object.get(name).ok_or_else(|| FieldError {
        path: name.to_string(),
        problem: "missing".into(),
    })?;
    T::from_json(v).map_err(|e| e.within(name))
}

/// `JsonField` for a struct: every field, by name (a field left out does not compile). Fields
/// added after recordings were made follow a `;` with the value older files imply
/// (`added = default`): written like the others, read as that value when absent.
macro_rules! json_struct {
    ($ty:ty { $($field:ident),+ $(,)? $(; $($added:ident = $default:expr),+ $(,)?)? }) => {
        impl JsonField for $ty {
            fn to_json(&self) -> Value {
                let mut m = Map::new();
                $(m.insert(stringify!($field).to_string(), self.$field.to_json());)+
                $($(m.insert(stringify!($added).to_string(), self.$added.to_json());)+)?
                Value::Object(m)
            }

            fn from_json(v: &Value) -> Result<Self, FieldError> {
                let m = v.as_object().ok_or_else(|| FieldError::expected("an object", v))?;
                Ok(Self {
                    $($field: field(m, stringify!($field))?,)+
                    $($($added: match m.get(stringify!($added)) {
                        Some(_) => field(m, stringify!($added))?,
                        None => $default,
                    },)+)?
                })
            }

            fn json_schema() -> Value {
                let mut properties = Map::new();
                $(properties.insert(stringify!($field).to_string(), schema_of::<$ty, _>(|s| &s.$field));)+
                $($(properties.insert(stringify!($added).to_string(), schema_of::<$ty, _>(|s| &s.$added));)+)?
                json!({
                    "type": "object",
                    "properties": Value::Object(properties),
                    "required": [$(stringify!($field)),+],
                })
            }
        }
    };
}

/// A field's schema, from an accessor (a macro cannot name a field's type).
fn schema_of<S, T: JsonField>(_field: fn(&S) -> &T) -> Value {
    T::json_schema()
}

// Every message and part, from the one list of their fields.
deckwatch_common::message_fields!(json_struct);

/// `JsonField` for a value per place of the pipeline (`StageTimes`, `DropCounts`): one integer
/// field per name of `NAMES`, spelled from the stage table, in its order; every one required.
macro_rules! json_per_stage {
    ($($ty:ty),+) => {$(
        impl JsonField for $ty {
            fn to_json(&self) -> Value {
                let mut m = Map::new();
                for (name, n) in self.named() {
                    m.insert(name.to_string(), n.to_json());
                }
                Value::Object(m)
            }

            fn from_json(v: &Value) -> Result<Self, FieldError> {
                let m = v.as_object().ok_or_else(|| FieldError::expected("an object", v))?;
                let mut values = Self::default().values();
                for (n, name) in values.iter_mut().zip(<$ty>::NAMES) {
                    *n = field(m, name)?;
                }
                Ok(Self::from_values(values))
            }

            fn json_schema() -> Value {
                let properties: Map<String, Value> = <$ty>::NAMES
                    .iter()
                    .map(|name| (name.to_string(), u64::json_schema()))
                    .collect();
                let required = <$ty>::NAMES;
                json!({
                    "type": "object",
                    "properties": Value::Object(properties),
                    "required": required,
                })
            }
        }
    )+};
}

json_per_stage!(StageTimes, DropCounts);

/// A MAVLink frame: its bytes as hex (pymavlink and any MAVLink parser read them), the name
/// and id for a reader without one.
impl JsonField for LinkTraffic {
    fn to_json(&self) -> Value {
        let hex: String = self.frame_bytes().iter().map(|b| format!("{b:02x}")).collect();
        json!({
            "time_ns": self.time_ns,
            "outgoing": self.outgoing.to_json(),
            "msg_id": self.msg_id,
            "name": self.name(),
            "frame": hex,
        })
    }

    fn from_json(v: &Value) -> Result<Self, FieldError> {
        let m = v
            .as_object()
            .ok_or_else(|| FieldError::expected("an object", v))?;
        let hex: String = v["frame"]
            .as_str()
            .map(str::to_string)
            .ok_or_else(|| FieldError {
                path: "frame".into(),
                problem: "expected a hex string".into(),
            })?;
        let bad = || FieldError {
            path: "frame".into(),
            problem: "not an even number of hex digits".into(),
        };
        if !hex.len().is_multiple_of(2) || !hex.is_ascii() {
            return Err(bad());
        }
        let frame = (0..hex.len() / 2)
            .map(|i| u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).map_err(|_| bad()))
            .collect::<Result<Vec<u8>, _>>()?;
        let name: String = v["name"].as_str().unwrap_or_default().to_string();
        let outgoing: WireBool = field(m, "outgoing")?;
        let mut out = LinkTraffic::new(
            field(m, "time_ns")?,
            outgoing.get(),
            field(m, "msg_id")?,
            &name,
            &frame,
        );
        out.outgoing = outgoing;
        Ok(out)
    }

    fn json_schema() -> Value {
        json!({
            "type": "object",
            "properties": {
                "time_ns": {"type": "integer"},
                "outgoing": {"type": ["boolean", "integer"]},
                "msg_id": {"type": "integer"},
                "name": {"type": "string"},
                "frame": {"type": "string", "description": "the MAVLink 2 frame, hex"},
            },
            "required": ["time_ns", "outgoing", "msg_id", "name", "frame"],
        })
    }
}

/// Whether two values hold the same bits in every float field (NaN equal to NaN) and the same
/// value in every other: the comparison of re-simulation and `deckwatch diff`.
pub fn same_bits<T: JsonField>(a: &T, b: &T) -> bool {
    a.to_json() == b.to_json()
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::messages::{DecisionReason, DecisionState};

    #[test]
    fn floats_read_back_to_the_same_bits() {
        for x in [
            0.1,
            -0.0,
            1.0 / 3.0,
            f64::MIN_POSITIVE,
            f64::MAX,
            5e-324,
            123456.789e-300,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ] {
            let back = f64::from_json(&serde_json::from_str(&x.to_json().to_string()).unwrap()).unwrap();
            assert_eq!(back.to_bits(), x.to_bits(), "{x:e}");
        }
        assert!(f64::from_json(&f64::NAN.to_json()).unwrap().is_nan());
    }

    #[test]
    fn a_decision_reads_back_field_for_field() {
        let mut d = LandingDecision {
            state: DecisionState::ClearToLand.into(),
            reason: DecisionReason::WithinCapacity.into(),
            calm_window_start_s: 12.345678901234567,
            ..Default::default()
        };
        d.attitude.rpy.roll = -0.0123456789;
        d.attitude.camera_position_m[2] = 1234.5678;
        d.stamp.seq = u64::MAX;
        let text = d.to_json().to_string();
        let back = LandingDecision::from_json(&serde_json::from_str(&text).unwrap()).unwrap();
        assert!(same_bits(&d, &back));
        assert_eq!(back.state, DecisionState::ClearToLand);
        assert_eq!(back.attitude.camera_position_m[2], 1234.5678);
        assert!(text.contains("\"state\":\"ClearToLand\""), "{text}");
    }

    #[test]
    fn bad_codes_survive_and_bad_json_names_the_field() {
        let d = LandingDecision {
            state: WireCode::from_code(77),
            watchdog: WireBool::from_byte(9),
            ..Default::default()
        };
        let back = LandingDecision::from_json(&d.to_json()).unwrap();
        assert_eq!(back.state.code(), 77);
        assert_eq!(back.watchdog.byte(), 9);
        let mut v = d.to_json();
        v["attitude"]["rpy"]["pitch"] = json!("level");
        let e = LandingDecision::from_json(&v).unwrap_err();
        assert_eq!(e.path, "attitude.rpy.pitch");
        v["attitude"]["rpy"] = json!({"roll": 0.0});
        let e = LandingDecision::from_json(&v).unwrap_err();
        assert_eq!(
            (e.path.as_str(), e.problem.as_str()),
            ("attitude.rpy.pitch", "missing")
        );
    }

    #[test]
    fn a_mavlink_frame_reads_back() {
        let t = LinkTraffic::new(42, true, 149, "LANDING_TARGET", &[0xfd, 0x1e, 0, 0, 7]);
        let back = LinkTraffic::from_json(&serde_json::from_str(&t.to_json().to_string()).unwrap()).unwrap();
        assert_eq!(back, t);
        assert_eq!(t.to_json()["frame"], "fd1e000007");
        let mut v = t.to_json();
        v["frame"] = json!("fd1");
        assert_eq!(LinkTraffic::from_json(&v).unwrap_err().path, "frame");
    }

    #[test]
    fn the_schema_names_every_field() {
        let s = AttitudeMessage::json_schema();
        assert_eq!(s["properties"]["rpy"]["properties"]["roll"]["type"][0], "number");
        assert_eq!(s["properties"]["stamp"]["properties"]["seq"]["type"], "integer");
        assert!(s["properties"]["valid"]["type"][0] == "boolean");
        assert_eq!(s["required"].as_array().unwrap().len(), 18);
    }

    /// The stage times and drop counts, indexed by the stage table, are written under the names
    /// their fields had (what the Python reader and older recordings have), every one required,
    /// and read back; one missing is named.
    #[test]
    fn the_stamp_keeps_its_names() {
        let stamp = FrameStamp {
            seq: 9,
            times: StageTimes::from_values([1, 2, 3, 4, 5, 6, 7, 8]),
            drops: DropCounts::from_values([10, 11, 12, 13, 14]),
        };
        let v = stamp.to_json();
        assert_eq!(
            v,
            json!({
                "seq": 9,
                "times": {
                    "captured_ns": 1,
                    "published_ns": 2,
                    "detect_received_ns": 3,
                    "detect_finished_ns": 4,
                    "estimate_received_ns": 5,
                    "estimate_finished_ns": 6,
                    "decide_received_ns": 7,
                    "decide_finished_ns": 8,
                },
                "drops": {"capture": 10, "bad_frames": 11, "detect": 12, "estimate": 13, "decide": 14},
            })
        );
        assert_eq!(FrameStamp::from_json(&v).unwrap(), stamp);
        let schema = FrameStamp::json_schema();
        assert_eq!(
            schema["properties"]["times"]["required"],
            json!(StageTimes::NAMES)
        );
        assert_eq!(
            schema["properties"]["drops"]["properties"]["bad_frames"],
            json!({"type": "integer"})
        );
        let mut cut = v.clone();
        cut["times"]
            .as_object_mut()
            .unwrap()
            .remove("estimate_finished_ns");
        let e = FrameStamp::from_json(&cut).unwrap_err();
        assert_eq!(e.to_string(), "times.estimate_finished_ns: missing");
    }
}
