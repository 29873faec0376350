//! The golden traces' settings identity (`ema::control::trace::settings_hash`) follows
//! every setting: for each trace case, every numeric or boolean leaf of its settings,
//! changed alone by the smallest step its type has (one unit in the last place of an `f32`,
//! one for an integer, the other value of a flag), gives another identity. A field left out
//! of the identity would let a saved trace pass against settings it was not made with.

use ema::control::trace::{settings_hash, CASES};
use ema::control::Settings;
use toml::Value;

/// Paths to every leaf that can be nudged, in document order.
fn leaves(v: &Value, path: &mut Vec<String>, out: &mut Vec<Vec<String>>) {
    match v {
        Value::Table(t) => {
            for (k, v) in t {
                path.push(k.clone());
                leaves(v, path, out);
                path.pop();
            }
        }
        Value::Array(a) => {
            for (k, v) in a.iter().enumerate() {
                path.push(k.to_string());
                leaves(v, path, out);
                path.pop();
            }
        }
        Value::Float(_) | Value::Integer(_) | Value::Boolean(_) => out.push(path.clone()),
        Value::String(_) | Value::Datetime(_) => {}
    }
}

fn at<'a>(v: &'a mut Value, path: &[String]) -> &'a mut Value {
    path.iter().fold(v, |v, k| match v {
        Value::Table(t) => t.get_mut(k).unwrap(),
        Value::Array(a) => &mut a[k.parse::<usize>().unwrap()],
        _ => panic!("not a container at {k}"),
    })
}

/// The smallest change of a leaf's value.
fn nudge(v: &mut Value) {
    *v = match *v {
        Value::Float(x) => {
            let x = x as f32;
            let next = if x == 0.0 {
                f32::MIN_POSITIVE
            } else {
                f32::from_bits(x.to_bits() + 1)
            };
            Value::Float(f64::from(next))
        }
        Value::Integer(n) => Value::Integer(n + 1),
        Value::Boolean(b) => Value::Boolean(!b),
        _ => unreachable!(),
    };
}

#[test]
fn every_setting_of_every_trace_case_changes_the_identity() {
    let mut checked = 0;
    for case in CASES {
        let settings = (case.settings)().unwrap();
        let doc = Value::try_from(settings).unwrap();
        // The document holds the settings exactly: nothing is lost on the way back.
        assert_eq!(doc.clone().try_into::<Settings>().unwrap(), settings);
        let mut paths = Vec::new();
        leaves(&doc, &mut Vec::new(), &mut paths);
        assert!(
            paths.len() >= 40,
            "{}: only {} leaves",
            case.name,
            paths.len()
        );
        let h = settings_hash(&settings);
        for path in &paths {
            let mut changed = doc.clone();
            nudge(at(&mut changed, path));
            let changed: Settings = changed.try_into().unwrap();
            assert_ne!(
                changed,
                settings,
                "{}: {} did not change",
                case.name,
                path.join(".")
            );
            assert_ne!(
                settings_hash(&changed),
                h,
                "{}: {} is not part of the settings identity",
                case.name,
                path.join(".")
            );
            checked += 1;
        }
    }
    eprintln!(
        "{checked} settings in {} trace cases, each changes the identity",
        CASES.len()
    );
}
