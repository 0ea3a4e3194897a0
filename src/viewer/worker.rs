//! Render workers: one thread per side (and one for references), each with its own
//! GPU `Session`, so the window never waits for the GPU and each side keeps its own
//! accumulation buffers and cone pyramids between frames.
//!
//! A worker is told what to render (a `Job`) and then works on its own: it traces
//! batches of frames, continuing the accumulation (`Session::render_frames`), sends
//! the running image after each batch, and stops at the job's cap. A newer job replaces
//! the current one between batches.

use std::sync::Arc;
use std::sync::mpsc::{Receiver, TryRecvError};
use std::thread::JoinHandle;
use std::time::Duration;

use crate::experiment::Experiment;
use crate::frame::Frame;
use crate::plan::Plan;
use crate::session::{Backend, Session};

/// What to render: `experiment` at `width` x `height`, accumulating up to `frames`.
#[derive(Clone, Debug)]
pub struct Job {
    /// The generation of the state it was made from; results carry it back.
    pub generation: u64,
    pub experiment: Arc<Experiment>,
    pub width: u32,
    pub height: u32,
    /// Frames to accumulate in all (1 where nothing is sampled).
    pub frames: u32,
    /// Time one batch of frames should take; the worker sizes its batches to it.
    pub batch_budget: Duration,
}

/// The running image of a job after a batch.
#[derive(Clone, Debug)]
pub struct Update {
    pub generation: u64,
    pub frame: Arc<Frame>,
    /// Frames accumulated so far.
    pub frames: u32,
    /// Frames the job accumulates in all: done when `frames == total`.
    pub total: u32,
    /// Trace time per frame of the latest batch (device timer where available).
    pub frame_time: Duration,
    /// The render plan, as `voxlab render` prints it.
    pub plan: String,
    /// The plan's warnings (`Plan::warnings`), shown beside it.
    pub warnings: Vec<String>,
}

/// A message from a worker.
#[derive(Clone, Debug)]
pub enum Report {
    Ready {
        adapter: String,
    },
    Update(Update),
    /// The job could not be rendered; the worker waits for the next one.
    Failed {
        generation: u64,
        message: String,
    },
}

/// A running worker thread; dropping it waits for the thread, which ends once every
/// sender of its job queue is gone.
pub struct Worker {
    thread: Option<JoinHandle<()>>,
}

impl Worker {
    /// Starts a worker on the job queue `jobs`; `report` takes each report and
    /// `notify` is called after it (the window's repaint).
    pub fn spawn(
        name: &str,
        jobs: Receiver<Job>,
        report: impl Fn(Report) + Send + 'static,
        notify: impl Fn() + Send + 'static,
    ) -> std::io::Result<Self> {
        let thread = std::thread::Builder::new()
            .name(format!("voxlab {name}"))
            .spawn(move || {
                run(jobs, |r| {
                    report(r);
                    notify();
                })
            })?;
        Ok(Self {
            thread: Some(thread),
        })
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The job a worker is on: its settings at the traced size, the frames it accumulates
/// in all, and those done.
struct Current {
    job: Job,
    settings: crate::render::RenderSettings,
    total: u32,
    done: u32,
}

fn run(jobs: Receiver<Job>, send: impl Fn(Report)) {
    let mut session = match Session::new(Backend::Gpu) {
        Ok(t) => t,
        Err(e) => {
            send(Report::Failed {
                generation: 0,
                message: e.to_string(),
            });
            return;
        }
    };
    send(Report::Ready {
        adapter: session
            .gpu()
            .map(|g| g.adapter_summary())
            .unwrap_or_default(),
    });
    let mut current: Option<Current> = None;
    // Time per frame of the latest batch, to size the next one.
    let mut per_frame: Option<Duration> = None;
    loop {
        // The newest job wins; with nothing left to do, wait for one.
        let idle = current.as_ref().is_none_or(|c| c.done >= c.total);
        let next = if idle {
            match jobs.recv() {
                Ok(j) => Some(j),
                Err(_) => return,
            }
        } else {
            None
        };
        let mut newest = next;
        loop {
            match jobs.try_recv() {
                Ok(j) => newest = Some(j),
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => return,
            }
        }
        if let Some(job) = newest {
            // Once per job: how many frames the plan accumulates.
            let settings = crate::render::RenderSettings {
                width: job.width,
                height: job.height,
                spp: job.frames.max(1),
                ..job.experiment.settings.clone()
            };
            let total = Plan::new(&job.experiment.scene, &settings).frames(&settings);
            current = Some(Current {
                job,
                settings,
                total,
                done: 0,
            });
        }
        let Some(Current {
            job,
            settings,
            total,
            done,
        }) = current.as_mut()
        else {
            continue;
        };
        let (e, total) = (&job.experiment, *total);
        let batch = match per_frame {
            Some(t) if !t.is_zero() => {
                (job.batch_budget.as_secs_f64() / t.as_secs_f64()).floor() as u32
            }
            _ => 1,
        }
        .clamp(1, total - *done);
        // A panic inside the tracer (a driver or validation failure wgpu reports by
        // panicking) becomes this job's error instead of a silently dead thread.
        let frames = *done..*done + batch;
        let rendered = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            session
                .render_frames(&e.scene, settings, frames)
                .map_err(anyhow::Error::new)
        }))
        .unwrap_or_else(|panic| {
            let what = panic
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| panic.downcast_ref::<&str>().copied())
                .unwrap_or("unknown panic");
            Err(anyhow::anyhow!("the tracer panicked: {what}"))
        });
        match rendered {
            Ok(image) => {
                // The device timer where there is one (the session's trace time): it
                // leaves out one-off costs (a kernel variant compiled on first use, a
                // pyramid build) that would make the adaptive resolution overreact to
                // the first frame.
                let frame_time = image.trace_time / batch;
                per_frame = Some(frame_time);
                *done += batch;
                let plan = image.plan.to_string();
                send(Report::Update(Update {
                    generation: job.generation,
                    frame: Arc::new(image.frame),
                    frames: *done,
                    total,
                    frame_time,
                    plan,
                    warnings: image.plan.warnings,
                }));
            }
            Err(err) => {
                send(Report::Failed {
                    generation: job.generation,
                    message: format!("{err:#}"),
                });
                current = None;
            }
        }
    }
}
