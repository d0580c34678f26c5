//! Trajectory playback for the viewer: a reader thread answers frame
//! requests (the latest request wins, so stepping fast never queues up
//! reads) and the window polls for what arrived, never waiting on it.

use crate::error::{Error, Result};
use crate::traj::{self, Frame, Pbc};
use std::sync::mpsc;
use std::time::{Duration, Instant};

pub struct Player {
    requests: mpsc::Sender<usize>,
    frames: mpsc::Receiver<Result<(usize, Frame)>>,
    /// Frames in the trajectory.
    pub n: usize,
    /// The frame on screen.
    pub current: usize,
    pub time_ps: Option<f64>,
    pub playing: bool,
    pub looping: bool,
    /// Playback speed, frames per second.
    pub speed: f64,
    pending: Option<usize>,
    last_step: Instant,
    /// Frames received and shown.
    pub shown: u64,
}

impl Player {
    /// Opens `path` for a topology of `atoms` spheres (`residues` for
    /// `--pbc whole`) and asks for frame 0.
    pub fn open(
        path: &std::path::Path,
        atoms: usize,
        pbc: Pbc,
        residues: Vec<u32>,
        kept: Option<Vec<u32>>,
    ) -> Result<Self> {
        let mut reader = traj::open(path)?;
        if reader.atoms() != atoms {
            return Err(Error::Input(format!(
                "the topology has {atoms} atoms, {} has {}",
                crate::output::shown(path),
                reader.atoms()
            )));
        }
        let n = reader.frames();
        let (req_tx, req_rx) = mpsc::channel::<usize>();
        let (tx, rx) = mpsc::channel::<Result<(usize, Frame)>>();
        std::thread::spawn(move || {
            while let Ok(mut k) = req_rx.recv() {
                // only the latest request matters
                while let Ok(later) = req_rx.try_recv() {
                    k = later;
                }
                let mut f = Frame::default();
                let r = reader.read(k, &mut f).map_err(Error::from).map(|()| {
                    f.keep(kept.as_deref());
                    traj::apply_pbc(pbc, &mut f.positions, f.cell.as_ref(), &residues);
                    (k, f)
                });
                if tx.send(r).is_err() {
                    break;
                }
            }
        });
        let mut p = Player {
            requests: req_tx,
            frames: rx,
            n,
            current: 0,
            time_ps: None,
            playing: true,
            looping: true,
            speed: 10.0,
            pending: None,
            last_step: Instant::now(),
            shown: 0,
        };
        p.request(0);
        Ok(p)
    }

    fn request(&mut self, k: usize) {
        if self.requests.send(k).is_ok() {
            self.pending = Some(k);
        }
    }

    /// A frame to show, if one arrived (never blocks). While playing, asks
    /// for the next frame once the previous arrived and its time is up;
    /// `eager` asks at once (smoke runs with `--frames N`).
    pub fn poll(&mut self, eager: bool) -> Result<Option<Frame>> {
        let mut got = None;
        while let Ok(r) = self.frames.try_recv() {
            let (k, f) = r?;
            if self.pending == Some(k) {
                self.pending = None;
            }
            self.current = k;
            self.time_ps = f.time_ps;
            got = Some(f);
        }
        if got.is_some() {
            self.shown += 1;
        }
        let due = eager || self.last_step.elapsed() >= Duration::from_secs_f64(1.0 / self.speed);
        if self.playing && self.pending.is_none() && due {
            let next = self.current + 1;
            if next < self.n {
                self.request(next);
            } else if self.looping {
                self.request(0);
            } else {
                self.playing = false;
            }
            self.last_step = Instant::now();
        }
        Ok(got)
    }

    /// Pauses and shows the frame `delta` away (clamped).
    pub fn step(&mut self, delta: i64) {
        self.playing = false;
        let k = (self.current as i64 + delta).clamp(0, self.n as i64 - 1) as usize;
        self.request(k);
    }

    pub fn toggle_play(&mut self) {
        self.playing = !self.playing;
    }

    pub fn faster(&mut self, factor: f64) {
        self.speed = (self.speed * factor).clamp(0.25, 240.0);
    }

    /// The title bar's part: frame, time, state.
    pub fn status(&self) -> String {
        let t = self
            .time_ps
            .map(|t| format!(" t {t:.1} ps"))
            .unwrap_or_default();
        format!(
            "frame {}/{}{t} | {} {:.3} frames/s{}",
            self.current,
            self.n,
            if self.playing { "playing" } else { "paused" },
            self.speed,
            if self.looping { " loop" } else { "" }
        )
    }
}
