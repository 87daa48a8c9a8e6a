//! Worker threads that share out one tick's robot visits ([`crate::scenario::Sim::set_threads`]).
//!
//! A tick's visits take a millisecond or two at 1000 robots, and the simulator hands them out
//! twenty to a few thousand times a second. Starting a thread for each tick costs 100-200 µs on
//! a 2-vCPU virtual machine (measured with `std::thread::scope`: most of it the hypervisor
//! waking the idle vCPU), as much as the work it would take over at a few hundred robots. So
//! the workers live as long as the simulation, and between two jobs each one spins for a
//! bounded time ([`SPIN`]) before it sleeps: while the simulation runs flat out the next tick
//! reaches a spinning worker (a hand-over of well under a microsecond); a caller that stops
//! stepping costs at most [`SPIN`] of one core per worker, then nothing.
//!
//! What it promises:
//! * [`Workers::run`] returns only once every share of the job has returned, on every thread,
//!   so a job may borrow the caller's data (the one `unsafe` below rests on this).
//! * A share that panics makes [`Workers::run`] panic on the caller's thread with the same
//!   payload, once every other share has finished; the workers stay usable.
//! * Dropping [`Workers`] stops and joins its threads.

use std::panic::{self, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::SeqCst};
use std::sync::{Arc, Mutex};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

/// How long an idle worker spins for the next job before it sleeps. Longer than the serial
/// part of a large team's tick (sensing, the radio, the world: a few hundred µs at 1000
/// robots), so a running simulation's worker never sleeps between ticks.
const SPIN: Duration = Duration::from_millis(2);

/// A job as the workers see it: the caller's `&dyn Fn(usize)`, its lifetime erased.
type Job = &'static (dyn Fn(usize) + Sync);

/// What the caller and one worker share.
struct Post {
    /// Bumped by the caller for each job (and to stop); the worker runs a job for each value.
    epoch: AtomicU64,
    /// The epoch of the last job the worker finished.
    done: AtomicU64,
    /// Set by the caller (with a last epoch) to end the worker.
    stop: AtomicBool,
    /// Whether the worker is asleep or about to sleep: the caller then wakes it.
    sleeping: AtomicBool,
    /// The current job, and the worker's share of it.
    job: Mutex<Option<(Job, usize)>>,
    /// A share's panic, for the caller to resume.
    panic: Mutex<Option<Box<dyn std::any::Any + Send>>>,
}

/// Threads that run the shares of a job beside the caller's thread.
pub(crate) struct Workers {
    posts: Vec<(Arc<Post>, JoinHandle<()>)>,
    epoch: u64,
}

impl Workers {
    /// `extra` workers (the caller's thread is the job's share 0, so a job has `extra + 1`
    /// shares). Errors if the system refuses a thread.
    pub(crate) fn new(extra: usize) -> std::io::Result<Workers> {
        let mut posts = Vec::with_capacity(extra);
        for k in 1..=extra {
            let post = Arc::new(Post {
                epoch: AtomicU64::new(0),
                done: AtomicU64::new(0),
                stop: AtomicBool::new(false),
                sleeping: AtomicBool::new(false),
                job: Mutex::new(None),
                panic: Mutex::new(None),
            });
            let theirs = Arc::clone(&post);
            let handle = thread::Builder::new().name(format!("ayllu-sim-{k}")).spawn(move || work(&theirs))?;
            posts.push((post, handle));
        }
        Ok(Workers { posts, epoch: 0 })
    }

    /// How many shares a job is cut into: the workers and the caller.
    pub(crate) fn shares(&self) -> usize {
        self.posts.len() + 1
    }

    /// Run `job(k)` for every share `k` in `0..self.shares()`: share 0 on this thread, the
    /// others on the workers, all at once; return when all have returned.
    pub(crate) fn run(&mut self, job: &(dyn Fn(usize) + Sync)) {
        // SAFETY: the erased reference is used only by the workers' shares of this job, and
        // this function does not return (nor unwind: `Wait` below waits for them when
        // dropped) before every worker has stored `done == epoch`, which it does after its
        // share returned and after it dropped its copy of the reference. So the reference
        // never outlives `job`'s borrow.
        let erased: Job = unsafe { std::mem::transmute::<&(dyn Fn(usize) + Sync), Job>(job) };
        self.epoch += 1;
        for (k, (post, handle)) in self.posts.iter().enumerate() {
            *lock(&post.job) = Some((erased, k + 1));
            post.epoch.store(self.epoch, SeqCst);
            if post.sleeping.load(SeqCst) {
                handle.thread().unpark();
            }
        }
        let wait = Wait { workers: self };
        let mine = panic::catch_unwind(AssertUnwindSafe(|| job(0)));
        drop(wait);
        if let Err(payload) = mine {
            panic::resume_unwind(payload);
        }
        for (post, _) in &self.posts {
            if let Some(payload) = lock(&post.panic).take() {
                panic::resume_unwind(payload);
            }
        }
    }
}

/// Waits, when dropped, for every worker to finish the current job.
struct Wait<'a> {
    workers: &'a Workers,
}

impl Drop for Wait<'_> {
    fn drop(&mut self) {
        for (post, _) in &self.workers.posts {
            let mut spins = 0u32;
            while post.done.load(SeqCst) != self.workers.epoch {
                spins = spins.wrapping_add(1);
                pause(spins);
            }
        }
    }
}

impl Drop for Workers {
    fn drop(&mut self) {
        self.epoch += 1;
        for (post, handle) in &self.posts {
            post.stop.store(true, SeqCst);
            post.epoch.store(self.epoch, SeqCst);
            handle.thread().unpark();
        }
        for (_, handle) in self.posts.drain(..) {
            // A worker's panics are caught, so this only fails if the thread itself died.
            let _ = handle.join();
        }
    }
}

/// A worker's loop: wait for a new epoch (spinning, then asleep), run its share, say done.
fn work(post: &Post) {
    let mut seen = 0;
    loop {
        let epoch = wait_for_epoch(post, seen);
        seen = epoch;
        if post.stop.load(SeqCst) {
            return;
        }
        if let Some((job, k)) = lock(&post.job).take() {
            if let Err(payload) = panic::catch_unwind(AssertUnwindSafe(|| job(k))) {
                *lock(&post.panic) = Some(payload);
            }
        }
        post.done.store(epoch, SeqCst);
    }
}

/// The first epoch after `seen`: spin for [`SPIN`], then sleep until woken.
fn wait_for_epoch(post: &Post, seen: u64) -> u64 {
    let start = Instant::now();
    let mut spins = 0u32;
    loop {
        let epoch = post.epoch.load(SeqCst);
        if epoch != seen {
            return epoch;
        }
        spins = spins.wrapping_add(1);
        // The clock is read every 256 turns: it costs more than a turn.
        if !spins.is_multiple_of(256) || start.elapsed() < SPIN {
            pause(spins);
            continue;
        }
        // Announce the sleep, then look once more: the caller stores the epoch before it
        // reads `sleeping`, and this stores `sleeping` before it reads the epoch (all SeqCst),
        // so either the caller sees the flag and unparks, or this sees the new epoch. An
        // unpark that comes before the park makes the park return at once.
        post.sleeping.store(true, SeqCst);
        if post.epoch.load(SeqCst) == seen {
            thread::park();
        }
        post.sleeping.store(false, SeqCst);
    }
}

/// One turn of a wait loop: a spin hint, and every 256th turn a yield, so that a thread
/// whose work is waited for gets the CPU if it shares one with the waiter (more threads
/// than CPUs, or a busy machine).
fn pause(spins: u32) {
    if spins.is_multiple_of(256) {
        thread::yield_now();
    } else {
        std::hint::spin_loop();
    }
}

/// A lock that a share's panic cannot poison for the others (the data is a plain slot).
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicUsize;

    #[test]
    fn every_share_runs_once_per_job_with_borrowed_data() {
        let mut workers = Workers::new(3).unwrap();
        assert_eq!(workers.shares(), 4);
        for round in 0..2000usize {
            let hits: Vec<AtomicUsize> = (0..4).map(|_| AtomicUsize::new(0)).collect();
            workers.run(&|k| {
                hits[k].fetch_add(round + 1, SeqCst);
            });
            for h in &hits {
                assert_eq!(h.load(SeqCst), round + 1);
            }
        }
    }

    #[test]
    fn a_worker_that_slept_is_woken() {
        let mut workers = Workers::new(1).unwrap();
        let count = AtomicUsize::new(0);
        for _ in 0..3 {
            // Longer than the spin: the worker is asleep when the next job comes.
            thread::sleep(SPIN * 3);
            workers.run(&|_| {
                count.fetch_add(1, SeqCst);
            });
        }
        assert_eq!(count.load(SeqCst), 6);
    }

    #[test]
    fn a_share_panic_reaches_the_caller_after_every_share_finished() {
        let mut workers = Workers::new(2).unwrap();
        let finished = AtomicUsize::new(0);
        let r = panic::catch_unwind(AssertUnwindSafe(|| {
            workers.run(&|k| {
                if k == 2 {
                    panic!("share two");
                }
                thread::sleep(Duration::from_millis(20));
                finished.fetch_add(1, SeqCst);
            });
        }));
        let payload = r.expect_err("the panic reaches the caller");
        assert_eq!(payload.downcast_ref::<&str>(), Some(&"share two"));
        assert_eq!(finished.load(SeqCst), 2, "the other shares had finished");
        // Still usable.
        let count = AtomicUsize::new(0);
        workers.run(&|_| {
            count.fetch_add(1, SeqCst);
        });
        assert_eq!(count.load(SeqCst), 3);
    }
}
