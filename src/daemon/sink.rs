//! Where the tick hands what is to be recorded: a recorder when the session is recorded (feature
//! `record`), nothing otherwise. Every call is non-blocking and allocation-free.

use crate::ipc::payload::{MeshHeaderV1, StatsV1, ToolFeedbackV1, ToolPoseV1};

/// Event kinds, numbered as `palpa.Event.Kind` in `proto/palpa.proto`.
pub mod event {
    /// A pose was rejected by the input checks.
    pub const INPUT_REJECTED: i32 = 1;
    /// A tool went stale.
    pub const DISCONNECT: i32 = 2;
    /// The divergence guard acted.
    pub const DIVERGENCE_GUARD: i32 = 3;
    /// A tick's compute exceeded the period.
    pub const SYNCHRONICITY_MISS: i32 = 4;
    /// The world was reset.
    pub const RESET: i32 = 6;
    /// The simulation was paused.
    pub const PAUSE: i32 = 7;
    /// The simulation was resumed.
    pub const RESUME: i32 = 8;
    /// A transection made a new body.
    pub const BODY_ADDED: i32 = 9;
    /// The session ended at this tick (the last one simulated).
    pub const SESSION_END: i32 = 10;
}

/// The recording side of a session: a recorder when the session is recorded (feature `record`), a
/// live view when it is watched (feature `live`); each gets every record.
#[derive(Default)]
pub struct RecordSink {
    #[cfg(feature = "record")]
    recorder: Option<crate::record::recorder::Recorder>,
    #[cfg(feature = "live")]
    live: Option<crate::record::live::LiveView>,
}

#[cfg(feature = "record")]
use crate::record::recorder::Record;

impl RecordSink {
    /// Records nothing.
    pub fn none() -> Self {
        Self::default()
    }

    /// Records into `recorder`.
    #[cfg(feature = "record")]
    pub fn to(recorder: crate::record::recorder::Recorder) -> Self {
        Self {
            recorder: Some(recorder),
            ..Self::default()
        }
    }

    /// Also shows the session live on `live`.
    #[cfg(feature = "live")]
    pub fn with_live(mut self, live: crate::record::live::LiveView) -> Self {
        self.live = Some(live);
        self
    }

    /// Hands the record `make` builds to the recorder and to the live view (built once for each).
    #[cfg(feature = "record")]
    fn each(&self, make: impl Fn() -> Record) {
        if let Some(r) = &self.recorder {
            r.push(make());
        }
        #[cfg(feature = "live")]
        if let Some(l) = &self.live {
            l.push(make());
        }
    }

    /// A pose used for tool `tool`, applied before stepping from `tick`.
    pub fn input(&self, tick: u64, tool: usize, pose: &ToolPoseV1, receive_wall_time_ns: u64) {
        #[cfg(feature = "record")]
        self.each(|| Record::Input {
            tick,
            tool: tool as u16,
            pose: *pose,
            receive_wall_time_ns,
        });
        #[cfg(not(feature = "record"))]
        let _ = (tick, tool, pose, receive_wall_time_ns);
    }

    /// The feedback of tool `tool` after a step.
    pub fn feedback(&self, tool: usize, feedback: &ToolFeedbackV1) {
        #[cfg(feature = "record")]
        self.each(|| Record::Feedback {
            tool: tool as u16,
            feedback: *feedback,
        });
        #[cfg(not(feature = "record"))]
        let _ = (tool, feedback);
    }

    /// A mesh message.
    pub fn mesh(&self, header: &MeshHeaderV1, bytes: &[u8]) {
        #[cfg(feature = "record")]
        if let Some(r) = &self.recorder {
            r.push_mesh(header, bytes);
        }
        #[cfg(feature = "live")]
        if let Some(l) = &self.live {
            l.push_mesh(header, bytes);
        }
        #[cfg(not(feature = "record"))]
        let _ = (header, bytes);
    }

    /// Loop statistics.
    pub fn stats(&self, stats: &StatsV1) {
        #[cfg(feature = "record")]
        self.each(|| Record::Stats(*stats));
        #[cfg(not(feature = "record"))]
        let _ = stats;
    }

    /// An event (`kind` from [`event`]); `tool` is `None` for the whole session.
    pub fn event(&self, tick: u64, kind: i32, tool: Option<usize>) {
        #[cfg(feature = "record")]
        self.each(|| Record::Event {
            tick,
            kind,
            tool: tool.map_or(u16::MAX, |t| t as u16),
        });
        #[cfg(not(feature = "record"))]
        let _ = (tick, kind, tool);
    }

    /// The session ended after the step that led to `tick` (written last, so a recording says how
    /// long its session ran even when nothing else was sent at its last ticks).
    pub fn session_end(&self, tick: u64) {
        self.event(tick, event::SESSION_END, None);
    }

    /// The divergence guard restored body `body` (for `cause`) in the step that ended at `tick`.
    pub fn guard(&self, tick: u64, body: usize, cause: crate::dynamics::guard::GuardCause) {
        #[cfg(feature = "record")]
        self.each(|| Record::Guard {
            tick,
            body: body.min(u16::MAX as usize) as u16,
            cause,
        });
        #[cfg(not(feature = "record"))]
        let _ = (tick, body, cause);
    }

    /// Announces the bodies a transection added in the step that ended at `world.tick` (those past
    /// `known`, which follows them). Allocation-free: the name travels in a fixed buffer.
    pub fn bodies_added(&self, world: &crate::world::World, known: &mut usize) {
        while *known < world.bodies.len() {
            #[cfg(feature = "record")]
            {
                let name = world.bodies[*known].name.as_bytes();
                let mut buffer = [0u8; crate::record::recorder::MAX_BODY_NAME];
                let len = name.len().min(buffer.len());
                buffer[..len].copy_from_slice(&name[..len]);
                self.each(|| Record::BodyAdded {
                    tick: world.tick,
                    body: (*known).min(u16::MAX as usize) as u16,
                    name: buffer,
                    len: len as u8,
                });
            }
            *known += 1;
        }
    }

    /// Records the recorder dropped so far.
    pub fn dropped(&self) -> u64 {
        #[cfg(feature = "record")]
        if let Some(r) = &self.recorder {
            return r.dropped();
        }
        0
    }

    /// Closes the recording (returns the messages written per topic and the drops) and stops the
    /// live view (see [`RecordSink::finish_all`] for its figures).
    #[cfg(feature = "record")]
    pub fn finish(
        self,
    ) -> Result<
        Option<crate::record::recorder::RecordingSummary>,
        crate::record::recorder::RecordError,
    > {
        self.finish_all().0
    }

    /// Closes the recording and stops the live view; returns what each did.
    #[cfg(feature = "record")]
    #[allow(clippy::type_complexity)]
    pub fn finish_all(
        self,
    ) -> (
        Result<
            Option<crate::record::recorder::RecordingSummary>,
            crate::record::recorder::RecordError,
        >,
        Option<LiveSummary>,
    ) {
        let recording = match self.recorder {
            Some(r) => r.finish().map(Some),
            None => Ok(None),
        };
        #[cfg(feature = "live")]
        let live = self.live.map(|l| l.finish());
        #[cfg(not(feature = "live"))]
        let live = None;
        (recording, live)
    }
}

/// What a live view did (`palpa serve --live`, feature `live`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LiveSummary {
    /// Messages published per topic (sent to every subscribed viewer).
    pub messages: std::collections::BTreeMap<String, u64>,
    /// Records the tick could not hand over (queue or mesh pool full).
    pub dropped: u64,
    /// Viewers that connected.
    pub viewers: u64,
}
