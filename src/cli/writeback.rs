//! Writing a large output so that the kernel starts putting it on disk while it is written.
//!
//! An output is written to a temporary file beside it and renamed over the old one. Before such
//! a rename returns, ext4 (with its default `auto_da_alloc`) starts the writeback of every page
//! the new file still has dirty. That way, after a crash the name holds the old file or the new
//! one, never an empty one. For the 72 MB output of the whole-path bench's sphere that is 20–40
//! ms of the rename, on the one thread that waits for it, while the other core is idle.
//!
//! So here, once an output passes [`CHUNK`], a second thread starts the writeback of each
//! chunk as soon as it is written (`sync_file_range` with `SYNC_FILE_RANGE_WRITE`). It waits for
//! no disk, only for the pages to be sent on their way. The rename then finds nothing left to
//! start, and the guarantee is the one the rename gave: the data is on its way to disk before
//! the new name is. Measured with `scripts/probes/replace-file.c` (docs/benchmarks.md, "The
//! whole process on this machine"), the rename of 72 MiB over the previous file took 23–33 ms
//! this way against 55–68 ms.
//!
//! Where `sync_file_range` is not available (outside Linux with glibc), outputs are written
//! as before.
//!
//! Before that, the output being replaced gives back its cached pages
//! ([`drop_cached_pages`]), so that the new file is written into them.

use std::fs::File;
use std::io::{IoSlice, Write};
use std::sync::mpsc;
use std::thread::Scope;

/// The writeback is started for each chunk this size, and each write is cut at a chunk's end
/// so that the chunk can be started while the next is written. Small outputs never reach it,
/// and never start the thread.
const CHUNK: u64 = 8 << 20;

/// Whether this platform can start a writeback.
const AVAILABLE: bool = cfg!(all(target_os = "linux", target_env = "gnu"));

/// Runs `write` on `file` (a new, empty file) with what it writes from, `held`, starting the
/// writeback of what it wrote chunk by chunk on a second thread, then closes the file and runs
/// `then` (the rename) while that thread may still be starting the last chunks: waiting for it
/// first took up to 30 ms more where it lagged, and the rename starts whatever it has not.
///
/// Once written, `held` is let go on a thread of its own while `then` runs ([`release_beside`]).
pub(super) fn write_then<T: Send>(
    file: File,
    held: T,
    write: impl FnOnce(&T, &mut dyn Write) -> std::io::Result<()>,
    then: impl FnOnce() -> std::io::Result<()>,
) -> std::io::Result<()> {
    std::thread::scope(|scope| {
        let mut out = ChunkedWriter::new(&file, scope);
        write(&held, &mut out)?;
        // The channel closes with `out`, and the thread ends after the chunks it was told of,
        // closing its own handle of the file.
        drop(out);
        drop(file);
        release_beside(scope, held);
        then()
    })
}

/// Drops `held` on a thread of the scope, so that its freeing overlaps the rename after it.
///
/// A rename over a previous output frees that file's blocks before it returns, and on a file
/// system mounted with `discard` (this project's machines) it sleeps in the disk's synchronous
/// discard meanwhile: 24–36 ms for the whole-path bench's 72 MB output, with both cores idle.
/// What the command line lets go after its write (the input's 56 MB mapping, the 16 MB of
/// tangents the output's pieces hold) took about 2 ms of a core, and the process's exit frees
/// whatever is left after it. Where no thread can be started, `held` is dropped here.
fn release_beside<'scope, T: Send + 'scope>(scope: &'scope Scope<'scope, '_>, held: T) {
    if !std::mem::needs_drop::<T>() {
        return;
    }
    // On failure the closure, and `held` in it, is dropped on this thread.
    let _ = std::thread::Builder::new().spawn_scoped(scope, move || drop(held));
}

/// A writer that tells the writeback thread how far the file is written, each [`CHUNK`].
struct ChunkedWriter<'scope, 'env, 'file> {
    file: &'file File,
    scope: &'scope Scope<'scope, 'env>,
    written: u64,
    /// How far the thread was told.
    announced: u64,
    /// The way to tell it, once it runs.
    written_up_to: Option<mpsc::Sender<u64>>,
}

impl<'scope, 'env, 'file> ChunkedWriter<'scope, 'env, 'file> {
    /// A writer at the start of `file`, its thread not started.
    fn new(file: &'file File, scope: &'scope Scope<'scope, 'env>) -> Self {
        ChunkedWriter {
            file,
            scope,
            written: 0,
            announced: 0,
            written_up_to: None,
        }
    }

    /// How much more may be written before the next chunk's end.
    fn room(&self) -> usize {
        if !AVAILABLE {
            return usize::MAX;
        }
        let to_next = CHUNK - self.written % CHUNK;
        usize::try_from(to_next).unwrap_or(usize::MAX)
    }

    fn advance(&mut self, n: usize) {
        self.written += n as u64;
        if !AVAILABLE || self.written - self.announced < CHUNK {
            return;
        }
        if self.written_up_to.is_none() {
            // Its own handle, so that this one can be closed before the rename.
            let Ok(file) = self.file.try_clone() else {
                return;
            };
            let (sender, receiver) = mpsc::channel::<u64>();
            self.scope.spawn(move || {
                let mut started = 0;
                for upto in receiver {
                    start_writeback(&file, started, upto - started);
                    started = upto;
                }
            });
            self.written_up_to = Some(sender);
        }
        let Some(sender) = &self.written_up_to else {
            return;
        };
        // A thread that has gone can only mean it panicked; the rename still starts the rest.
        let _ = sender.send(self.written);
        self.announced = self.written;
    }
}

impl Write for ChunkedWriter<'_, '_, '_> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = (&*self.file).write(&buf[..buf.len().min(self.room())])?;
        self.advance(n);
        Ok(n)
    }

    /// Writes at most up to the next chunk's end: a short write, which callers resume.
    fn write_vectored(&mut self, bufs: &[IoSlice<'_>]) -> std::io::Result<usize> {
        let mut room = self.room();
        let mut cut = Vec::with_capacity(bufs.len());
        for buf in bufs {
            if room == 0 {
                break;
            }
            let take = buf.len().min(room);
            cut.push(IoSlice::new(&buf[..take]));
            room -= take;
        }
        let n = (&*self.file).write_vectored(&cut)?;
        self.advance(n);
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        (&*self.file).flush()
    }
}

/// Drops from the page cache the pages of the file `path` names, which the caller is about to
/// replace, so that the new output's pages can be the old one's instead of memory the machine
/// has not touched lately. The rename frees those pages anyway, but only once the new file has
/// been written beside them.
///
/// On this project's machines (virtual machines whose host backs guest memory only once it is
/// used, and takes back memory the guest has left free for a while), a write into pages of such
/// memory ran at 0.4 GB/s, against 5 GB/s into pages freed a moment before: 20 ms against 1.6 ms
/// for each 8 MiB of the whole-path bench's 72 MB output. Measured on that sphere, 14 interleaved
/// runs of `tspace process` over their previous outputs, half a second apart: a median of 174 ms
/// (107–333) without the drop and 116 ms (110–159) with it. Where memory is real, the drop only
/// moves the freeing of those pages earlier.
///
/// Only for a regular file of one link and at least [`CHUNK`]: another name for the same file
/// still needs its pages, and a small file's are not worth the calls. Pages mapped by a process
/// stay, and dirty pages are not dropped (the kernel starts their writeback instead: wasted
/// where another program wrote the old file moments ago and never flushed it, since a file
/// replaced is thrown away unwritten; tspace's own outputs have had their writeback started).
#[cfg(target_os = "linux")]
pub(super) fn drop_cached_pages(path: &std::path::Path) {
    use std::os::fd::AsRawFd;
    use std::os::unix::fs::MetadataExt;
    let Ok(old) = File::open(path) else {
        return;
    };
    let Ok(metadata) = old.metadata() else {
        return;
    };
    if !metadata.is_file() || metadata.nlink() != 1 || metadata.len() < CHUNK {
        return;
    }
    // SAFETY: the descriptor is that of `old`, open for the whole call, and the call takes no
    // memory of ours: only numbers. It is advice; where it fails, the rename frees the pages.
    unsafe {
        libc::posix_fadvise(old.as_raw_fd(), 0, 0, libc::POSIX_FADV_DONTNEED);
    }
}

#[cfg(not(target_os = "linux"))]
pub(super) fn drop_cached_pages(_: &std::path::Path) {}

/// Starts the writeback of `length` bytes of `file` from `offset`, waiting for no disk. A hint:
/// where it fails, the rename starts them as before.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn start_writeback(file: &File, offset: u64, length: u64) {
    use std::os::fd::AsRawFd;
    let (Ok(offset), Ok(length)) = (i64::try_from(offset), i64::try_from(length)) else {
        return;
    };
    // SAFETY: the descriptor is that of `file`, open for the whole call (the caller borrows
    // it), and the call takes no memory of ours: only numbers.
    unsafe {
        libc::sync_file_range(
            file.as_raw_fd(),
            offset,
            length,
            libc::SYNC_FILE_RANGE_WRITE,
        );
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn start_writeback(_: &File, _: u64, _: u64) {}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;
    use std::path::PathBuf;

    /// A folder of this process's own, for one test.
    fn scratch(test: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("tspace-writeback-{test}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("a temporary folder");
        dir
    }

    /// What is written arrives whole and in order, through writes and vectored writes that
    /// cross chunk ends (the writer cuts them there, and the callers resume), for outputs
    /// below one chunk and across several.
    #[test]
    fn written_bytes_arrive_whole_across_chunks() {
        let dir = scratch("chunks");
        for len in [0usize, 1000, CHUNK as usize + 17, 3 * CHUNK as usize + 5] {
            let data: Vec<u8> = (0..len).map(|i| (i * 7 + i / 251) as u8).collect();
            let path = dir.join(format!("out-{len}"));
            let file = File::create(&path).expect("a new file");
            write_then(
                file,
                (),
                |(), out| {
                    let (head, rest) = data.split_at(len / 3);
                    out.write_all(head)?;
                    let (middle, tail) = rest.split_at(rest.len() / 2);
                    let mut slices = [IoSlice::new(middle), IoSlice::new(tail)];
                    let mut left = &mut slices[..];
                    while !left.is_empty() {
                        let n = out.write_vectored(left)?;
                        assert!(n > 0 || left.iter().all(|s| s.is_empty()));
                        if n == 0 {
                            break;
                        }
                        IoSlice::advance_slices(&mut left, n);
                    }
                    out.flush()
                },
                || Ok(()),
            )
            .expect("written");
            let mut back = Vec::new();
            File::open(&path)
                .and_then(|mut f| f.read_to_end(&mut back))
                .expect("read back");
            assert_eq!(back.len(), data.len());
            assert!(back == data, "the bytes of a {len}-byte output differ");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// No write crosses a chunk's end, so that each chunk is started as soon as it is whole.
    #[test]
    fn writes_stop_at_chunk_ends() {
        let dir = scratch("ends");
        let file = File::create(dir.join("out")).expect("a new file");
        let big = vec![1u8; CHUNK as usize + 100];
        write_then(
            file,
            (),
            |(), out| {
                let first = out.write(&big[..100])?;
                assert_eq!(first, 100);
                let second = out.write_vectored(&[IoSlice::new(&big), IoSlice::new(&big)])?;
                if AVAILABLE {
                    assert_eq!(second, CHUNK as usize - 100);
                }
                Ok(())
            },
            || Ok(()),
        )
        .expect("written");
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// What the write read from is let go after the write and before `write_then` returns, on
    /// a thread other than the one that renames, and never while the write may still read it.
    #[test]
    fn what_was_written_from_goes_beside_the_rename() {
        use std::sync::Mutex;
        use std::sync::atomic::{AtomicBool, Ordering};
        struct Held<'a> {
            dropped: &'a Mutex<Option<std::thread::ThreadId>>,
        }
        impl Drop for Held<'_> {
            fn drop(&mut self) {
                let mut dropped = self.dropped.lock().unwrap_or_else(|e| e.into_inner());
                *dropped = Some(std::thread::current().id());
            }
        }
        let dir = scratch("release");
        let dropped = Mutex::new(None);
        let renamed = AtomicBool::new(false);
        let file = File::create(dir.join("out")).expect("a new file");
        write_then(
            file,
            Held { dropped: &dropped },
            |held, out| {
                assert!(held.dropped.lock().expect("not poisoned").is_none());
                out.write_all(b"written")
            },
            || {
                renamed.store(true, Ordering::SeqCst);
                Ok(())
            },
        )
        .expect("written");
        assert!(renamed.load(Ordering::SeqCst));
        let dropped_on = dropped.lock().expect("not poisoned").take();
        assert!(dropped_on.is_some(), "held was not let go");
        assert_ne!(dropped_on, Some(std::thread::current().id()));
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// The thread starts once the output passes a chunk, and is told of each chunk's end;
    /// smaller outputs never start it.
    #[test]
    fn the_thread_starts_only_past_a_chunk() {
        let dir = scratch("thread");
        let file = File::create(dir.join("out")).expect("a new file");
        std::thread::scope(|scope| {
            let mut out = ChunkedWriter::new(&file, scope);
            out.write_all(&vec![0u8; CHUNK as usize - 1])
                .expect("written");
            assert!(out.written_up_to.is_none());
            out.write_all(&[0u8; 1]).expect("written");
            assert_eq!(out.written_up_to.is_some(), AVAILABLE);
            assert_eq!(out.announced, if AVAILABLE { CHUNK } else { 0 });
        });
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// How many of the file's pages are in the page cache, by `mincore` over a map of it.
    #[cfg(target_os = "linux")]
    fn resident_pages(path: &std::path::Path) -> usize {
        let file = File::open(path).expect("readable");
        // SAFETY: a read-only map of this test's own file, which nothing writes meanwhile.
        let map = unsafe { memmap2::Mmap::map(&file) }.expect("mapped");
        let page = 4096;
        let mut resident = vec![0u8; map.len().div_ceil(page)];
        // SAFETY: `resident` has a byte for each page of the map, which stays mapped for the
        // call; mincore only writes those bytes.
        let status = unsafe {
            libc::mincore(
                map.as_ptr() as *mut libc::c_void,
                map.len(),
                resident.as_mut_ptr(),
            )
        };
        assert_eq!(status, 0, "mincore");
        resident.iter().filter(|&&r| r & 1 != 0).count()
    }

    /// A replaced output's clean pages leave the cache; a file with a second name keeps them,
    /// and so does one below a chunk. Where the file system keeps clean pages whatever it is
    /// advised (tmpfs holds its files only there), as a control file advised directly shows,
    /// the test says so and checks nothing.
    #[cfg(target_os = "linux")]
    #[test]
    fn a_replaced_outputs_pages_are_dropped_unless_it_has_another_name() {
        use std::os::fd::AsRawFd;
        let dir = scratch("drop");
        let write_synced = |name: &str, len: usize| {
            let path = dir.join(name);
            let mut file = File::create(&path).expect("a new file");
            file.write_all(&vec![7u8; len]).expect("written");
            file.sync_all()
                .expect("on disk, so that its pages are clean");
            path
        };
        let big = CHUNK as usize + 4096;
        let control = write_synced("control", big);
        let control_before = resident_pages(&control);
        let file = File::open(&control).expect("readable");
        // SAFETY: the descriptor is `file`'s, open for the call, which takes only numbers.
        unsafe { libc::posix_fadvise(file.as_raw_fd(), 0, 0, libc::POSIX_FADV_DONTNEED) };
        if resident_pages(&control) > control_before / 2 {
            let _ = std::fs::remove_dir_all(&dir);
            eprintln!("skipped: this file system keeps the pages of a file advised to drop them");
            return;
        }
        let lone = write_synced("lone", big);
        let linked = write_synced("linked", big);
        std::fs::hard_link(&linked, dir.join("second-name")).expect("a second link");
        let small = write_synced("small", 64 << 10);
        let before = [&lone, &linked, &small].map(|p| resident_pages(p));
        for path in [&lone, &linked, &small] {
            drop_cached_pages(path);
        }
        let after = [&lone, &linked, &small].map(|p| resident_pages(p));
        let _ = std::fs::remove_dir_all(&dir);
        assert!(after[0] < before[0] / 2, "{before:?} -> {after:?}");
        assert_eq!(after[1], before[1], "a file with two names keeps its pages");
        assert_eq!(after[2], before[2], "a file below a chunk keeps its pages");
    }
}
