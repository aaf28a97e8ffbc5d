//! Cancellation of a long render: a flag a caller sets from any thread, checked by every CPU
//! estimator between chunks of its per-receiver loop (and between views), so `estimate` stops
//! within a chunk's time and returns [`Error::Cancelled`].
//!
//! One token can be handed to an estimator ([`SoftShadowEstimator::set_cancel`]) and kept by the
//! caller: clones share the flag. Once cancelled, a token stays cancelled; give the estimator a
//! fresh token ([`Cancel::new`]) to render again. After a cancelled `estimate` the content of V is
//! unspecified (some receivers done, others not): it is never reported as a success.
//!
//! The check is one relaxed atomic load per chunk of [`CHUNK`] receivers (and an atomic add of
//! the chunk's length to [`Cancel::progress`]): nothing measurable next to the chunk's work.
//!
//! [`SoftShadowEstimator::set_cancel`]: crate::SoftShadowEstimator::set_cancel
use crate::{Error, Result};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;

/// Items per chunk of [`Cancel::par_map_reduce`] (and its short forms): the flag is read
/// once per chunk. Small enough that a cancellation takes effect within a few milliseconds on
/// every estimator; large enough that the check costs nothing.
pub const CHUNK: usize = 256;

/// A cancellation token: a cheap, clonable handle on a shared flag (and a progress counter).
///
/// ```
/// use shadow_map_core::{Cancel, Error};
///
/// let cancel = Cancel::new();
/// let mut v = vec![0.0f32; 10_000];
/// // An estimator's per-receiver loop: f(k, &mut v[k]) in parallel, chunk by chunk.
/// let done: usize = cancel.par_sum(&mut v, |k, x| {
///     *x = k as f32;
///     1
/// })?;
/// assert_eq!(done, 10_000);
/// assert_eq!(cancel.progress(), 10_000);
///
/// // Set from any thread (here: a clone, as another thread would hold it).
/// let handle = cancel.clone();
/// std::thread::spawn(move || handle.cancel()).join().unwrap();
/// assert!(cancel.is_cancelled());
/// let out = cancel.par_for_each(&mut v, |_, x| *x = 0.0);
/// assert!(matches!(out, Err(Error::Cancelled)));
/// assert!(matches!(cancel.check(), Err(Error::Cancelled)));
/// # Ok::<(), shadow_map_core::Error>(())
/// ```
#[derive(Debug, Clone, Default)]
pub struct Cancel {
    inner: Arc<Inner>,
}

#[derive(Debug, Default)]
struct Inner {
    cancelled: AtomicBool,
    done: AtomicU64,
}

impl Cancel {
    /// A token that is not cancelled.
    pub fn new() -> Self {
        Self::default()
    }
    /// Sets the flag (from any thread, through any clone). Idempotent; it is never cleared.
    pub fn cancel(&self) {
        self.inner.cancelled.store(true, Ordering::Relaxed);
    }
    /// Whether [`cancel`](Self::cancel) was called on this token or a clone of it.
    #[inline]
    pub fn is_cancelled(&self) -> bool {
        self.inner.cancelled.load(Ordering::Relaxed)
    }
    /// `Err(`[`Error::Cancelled`]`)` once cancelled, else `Ok(())`: the check between views and
    /// stages (`cancel.check()?`).
    #[inline]
    pub fn check(&self) -> Result<()> {
        if self.is_cancelled() {
            Err(Error::Cancelled)
        } else {
            Ok(())
        }
    }
    /// Items (receivers, per view for multi-view estimators) finished so far by the loops that
    /// check this token, over the token's life: a caller's progress display, or proof that a
    /// render has started.
    pub fn progress(&self) -> u64 {
        self.inner.done.load(Ordering::Relaxed)
    }
    /// Adds `n` finished items to [`progress`](Self::progress) (for a loop with chunks of its own,
    /// e.g. the reference's).
    #[inline]
    pub fn add_progress(&self, n: usize) {
        self.inner.done.fetch_add(n as u64, Ordering::Relaxed);
    }
    /// Runs `f(k, &mut v[k])` for every `k` in parallel (rayon), in chunks of [`CHUNK`], folding
    /// the results with `op` from `identity` (as rayon's `reduce`). The flag is read before each
    /// chunk: once cancelled, the remaining chunks are skipped and the result is
    /// `Err(`[`Error::Cancelled`]`)` (also when the flag was set after the last chunk began).
    pub fn par_map_reduce<T, R>(
        &self,
        v: &mut [T],
        f: impl Fn(usize, &mut T) -> R + Sync + Send,
        identity: impl Fn() -> R + Sync + Send,
        op: impl Fn(R, R) -> R + Sync + Send,
    ) -> Result<R>
    where
        T: Send,
        R: Send,
    {
        let out = v
            .par_chunks_mut(CHUNK)
            .enumerate()
            .map(|(c, chunk)| {
                if self.is_cancelled() {
                    return identity();
                }
                let base = c * CHUNK;
                let r = chunk
                    .iter_mut()
                    .enumerate()
                    .fold(identity(), |acc, (i, x)| op(acc, f(base + i, x)));
                self.add_progress(chunk.len());
                r
            })
            .reduce(&identity, &op);
        self.check()?;
        Ok(out)
    }
    /// [`par_map_reduce`](Self::par_map_reduce) summing `f`'s results (a count).
    pub fn par_sum<T, R>(
        &self,
        v: &mut [T],
        f: impl Fn(usize, &mut T) -> R + Sync + Send,
    ) -> Result<R>
    where
        T: Send,
        R: Send + std::iter::Sum<R>,
    {
        self.par_map_reduce(
            v,
            f,
            || std::iter::empty::<R>().sum(),
            |a, b| [a, b].into_iter().sum(),
        )
    }
    /// [`par_map_reduce`](Self::par_map_reduce) of an `f` that returns nothing.
    pub fn par_for_each<T: Send>(
        &self,
        v: &mut [T],
        f: impl Fn(usize, &mut T) + Sync + Send,
    ) -> Result<()> {
        self.par_map_reduce(v, f, || (), |(), ()| ())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cancelled_token_skips_every_chunk_and_says_so() {
        let c = Cancel::new();
        c.cancel();
        let mut v = vec![0u32; 3 * CHUNK + 1];
        let out = c.par_sum(&mut v, |_, x| {
            *x = 1;
            1usize
        });
        assert!(matches!(out, Err(Error::Cancelled)));
        assert!(v.iter().all(|x| *x == 0), "a chunk ran after cancel");
        assert_eq!(c.progress(), 0);
        assert_eq!(Error::Cancelled.to_string(), "cancelled");
    }

    #[test]
    fn cancelling_mid_loop_stops_the_remaining_chunks() {
        let c = Cancel::new();
        let mut v = vec![0u8; 1000 * CHUNK];
        // Chunk 0 cancels: with rayon's splitting, far from every other chunk runs after it.
        let out = c.par_for_each(&mut v, |k, x| {
            if k == 0 {
                c.cancel();
            }
            *x = 1;
        });
        assert!(matches!(out, Err(Error::Cancelled)));
        let ran = v.iter().filter(|x| **x == 1).count();
        assert!(ran < v.len(), "every chunk ran");
        assert_eq!(c.progress() as usize, ran);
    }

    #[test]
    fn reduce_folds_every_element_once() {
        let c = Cancel::new();
        let mut v: Vec<u64> = (0..10_000).collect();
        let (n, s) = c
            .par_map_reduce(
                &mut v,
                |k, x| (1u64, *x + k as u64),
                || (0, 0),
                |a, b| (a.0 + b.0, a.1 + b.1),
            )
            .unwrap();
        assert_eq!((n, s), (10_000, 2 * (0..10_000u64).sum::<u64>()));
    }
}
