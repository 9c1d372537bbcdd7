//! The JSON schemas of the run's channels (MCAP schema encoding `jsonschema`, message encoding
//! `json`). The two `foxglove.*` ones follow the fields of Foxglove's well-known schemas of the
//! same names, which is what makes the viewers' 3D panel draw them; the `omnibench.*` ones are
//! ours, shown by the plot, table and raw-message panels.

/// `foxglove.PoseInFrame`: a pose (position, orientation quaternion) in a frame at a time.
pub const POSE_IN_FRAME: &str = r#"{
  "title": "foxglove.PoseInFrame",
  "description": "A timestamped pose for an object or reference frame in 3D space",
  "type": "object",
  "required": ["timestamp", "frame_id", "pose"],
  "properties": {
    "timestamp": {"type": "object", "properties": {"sec": {"type": "integer", "minimum": 0}, "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}},
    "frame_id": {"type": "string"},
    "pose": {"type": "object", "properties": {
      "position": {"type": "object", "properties": {"x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"}}},
      "orientation": {"type": "object", "properties": {"x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"}, "w": {"type": "number"}}}
    }}
  }
}"#;

/// `foxglove.FrameTransform`: the transform from a parent frame to a child frame.
pub const FRAME_TRANSFORM: &str = r#"{
  "title": "foxglove.FrameTransform",
  "description": "A transform between two reference frames in 3D space",
  "type": "object",
  "required": ["timestamp", "parent_frame_id", "child_frame_id", "translation", "rotation"],
  "properties": {
    "timestamp": {"type": "object", "properties": {"sec": {"type": "integer", "minimum": 0}, "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}},
    "parent_frame_id": {"type": "string"},
    "child_frame_id": {"type": "string"},
    "translation": {"type": "object", "properties": {"x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"}}},
    "rotation": {"type": "object", "properties": {"x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"}, "w": {"type": "number"}}}
  }
}"#;

/// `omnibench.PoseError`: an estimate against the truth at the same time.
pub const POSE_ERROR: (&str, &str) = (
    "omnibench.PoseError",
    r#"{
  "title": "omnibench.PoseError",
  "description": "An estimated pose against the true one: distance and heading difference",
  "type": "object",
  "required": ["position_mm", "heading_deg"],
  "properties": {
    "position_mm": {"type": "number", "description": "distance between the estimated and the true position, millimetres"},
    "heading_deg": {"type": "number", "description": "estimated minus true heading, degrees, in (-180, 180]"}
  }
}"#,
);

/// `omnibench.Wheels`: the master's drive wheels.
pub const WHEELS: (&str, &str) = (
    "omnibench.Wheels",
    r#"{
  "title": "omnibench.Wheels",
  "description": "The master's wheel speed commands and motor duties",
  "type": "object",
  "required": ["cmd_m_s", "duty_permille"],
  "properties": {
    "cmd_m_s": {"type": "array", "items": {"type": "number"}, "description": "each wheel's commanded rim speed, m/s"},
    "duty_permille": {"type": "array", "items": {"type": "integer"}, "description": "each motor's PWM duty, signed, per mille"}
  }
}"#,
);

/// `omnibench.Status`: the master's status flags.
pub const STATUS: (&str, &str) = (
    "omnibench.Status",
    r#"{
  "title": "omnibench.Status",
  "description": "The master's status word and the names of the flags set in it (docs/protocol.md)",
  "type": "object",
  "required": ["flags", "set"],
  "properties": {
    "flags": {"type": "integer"},
    "set": {"type": "array", "items": {"type": "string"}}
  }
}"#,
);

/// `omnibench.Encoders`: the measuring wheels' encoder counts.
pub const ENCODERS: (&str, &str) = (
    "omnibench.Encoders",
    r#"{
  "title": "omnibench.Encoders",
  "description": "Each measuring wheel's encoder count (quadrature, x4), and the edges seen (recordings)",
  "type": "object",
  "required": ["counts"],
  "properties": {
    "counts": {"type": "array", "items": {"type": "integer"}},
    "edges": {"type": "integer", "description": "encoder edges (events) so far"}
  }
}"#,
);

/// `omnibench.Link`: a serial link's counters.
pub const LINK: (&str, &str) = (
    "omnibench.Link",
    r#"{
  "title": "omnibench.Link",
  "description": "Counters of the serial link between the host and the master, since the run started",
  "type": "object",
  "additionalProperties": {"type": "number"}
}"#,
);

#[cfg(test)]
mod tests {
    #[test]
    fn every_schema_is_json_with_its_title() {
        for (name, text) in [
            ("foxglove.PoseInFrame", super::POSE_IN_FRAME),
            ("foxglove.FrameTransform", super::FRAME_TRANSFORM),
            super::POSE_ERROR,
            super::WHEELS,
            super::STATUS,
            super::ENCODERS,
            super::LINK,
        ] {
            let v: serde_json::Value = serde_json::from_str(text).unwrap();
            assert_eq!(v["title"], name);
            assert_eq!(v["type"], "object");
        }
    }
}
