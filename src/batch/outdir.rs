//! The output directory: an exclusive lock, atomic writes, and containment.
//!
//! Every file texsyn writes goes to a temporary name in its final directory and is renamed into
//! place, so a run killed at any instant leaves only complete files (plus temporaries, which the
//! next run removes). The lock is an OS file lock, released by the kernel when the process dies,
//! so a killed run never leaves it stuck. Paths are checked to resolve inside the directory, so a
//! symlink planted in it cannot redirect a write elsewhere.

use crate::digest::{Digest, Hasher};
use crate::error::Error;
use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

const LOCK_NAME: &str = ".texsyn.lock";
const TMP_SUFFIX: &str = ".texsyn-tmp";

/// An output directory held exclusively by this process.
pub struct OutDir {
    root: PathBuf,
    /// Marks this holder's temporaries (`""` for a whole-directory run; the shard for a shard).
    tag: String,
    canonical: PathBuf,
    _lock: File,
}

static COUNTER: AtomicU64 = AtomicU64::new(0);

impl OutDir {
    /// Creates the directory if needed and takes its lock, or explains who holds it.
    pub fn open(root: &Path) -> Result<OutDir, Error> {
        OutDir::open_part(root, None)
    }

    /// Like [`OutDir::open`] for one shard of a run split across machines: the lock is the
    /// shard's own (an OS lock on a shared file system cannot be trusted across nodes, and shards
    /// write disjoint files), and only the shard's own stale temporaries are removed, never the
    /// in-flight ones of shards running elsewhere.
    pub fn open_part(root: &Path, part: Option<&str>) -> Result<OutDir, Error> {
        std::fs::create_dir_all(root).map_err(|e| Error::io(root, "create output directory", e))?;
        let canonical = root.canonicalize().map_err(|e| Error::io(root, "resolve", e))?;
        let lock_path = match part {
            None => root.join(LOCK_NAME),
            Some(p) => root.join(format!(".texsyn.{p}.lock")),
        };
        // Never through a link: a symlink or hard link planted at the lock's name would make the
        // PID below overwrite a file outside the output directory.
        let mut lock = crate::files::open_no_follow(&lock_path).map_err(|e| Error::io(&lock_path, "open lock file", e))?;
        match lock.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => {
                let holder = crate::files::read_limited(&lock_path, 64)
                    .ok()
                    .and_then(|b| String::from_utf8(b).ok())
                    .and_then(|s| s.trim().parse().ok());
                return Err(Error::Locked { dir: root.to_path_buf(), holder });
            }
            Err(std::fs::TryLockError::Error(e)) => return Err(Error::io(&lock_path, "lock", e)),
        }
        lock.set_len(0).ok();
        let _ = write!(lock, "{}", std::process::id());
        let tag = part.map(|p| format!("{p}.")).unwrap_or_default();
        let dir = OutDir { root: root.to_path_buf(), tag, canonical, _lock: lock };
        dir.remove_stale_temporaries();
        Ok(dir)
    }

    pub fn root(&self) -> &Path {
        &self.root
    }

    /// The absolute path of a relative output path, after checking that its directory resolves
    /// inside the output directory (creating the directories as needed).
    pub fn resolve(&self, rel: &str) -> Result<PathBuf, Error> {
        let path = self.root.join(rel);
        let parent = path.parent().expect("a file inside the root has a parent");
        std::fs::create_dir_all(parent).map_err(|e| Error::io(parent, "create directory", e))?;
        let real_parent = parent.canonicalize().map_err(|e| Error::io(parent, "resolve", e))?;
        if !real_parent.starts_with(&self.canonical) {
            return Err(Error::Containment {
                path: PathBuf::from(rel),
                reason: format!("would be written to {}, outside the output directory (a symlink?); refusing", real_parent.display()),
            });
        }
        if let Ok(meta) = std::fs::symlink_metadata(&path)
            && meta.file_type().is_symlink()
        {
            return Err(Error::Containment {
                path: PathBuf::from(rel),
                reason: "is a symlink in the output directory; refusing to write through it".into(),
            });
        }
        Ok(path)
    }

    /// Writes what `produce` writes to the relative path atomically, as it is produced (nothing
    /// is held in memory but a small buffer); returns `produce`'s result and the file's digest.
    pub fn write_streamed<T>(&self, rel: &str, produce: impl FnOnce(&mut dyn Write) -> std::io::Result<T>) -> Result<(T, Digest), Error> {
        let path = self.resolve(rel)?;
        write_tagged_with(&path, &self.tag, produce)
    }

    /// Writes `bytes` to the relative path atomically.
    pub fn write(&self, rel: &str, bytes: &[u8]) -> Result<PathBuf, Error> {
        let path = self.resolve(rel)?;
        write_tagged(&path, bytes, &self.tag)?;
        Ok(path)
    }

    /// Removes temporaries left by a killed run.
    fn remove_stale_temporaries(&self) {
        fn walk(dir: &Path, tag: &str) {
            let Ok(entries) = std::fs::read_dir(dir) else { return };
            for e in entries.flatten() {
                let p = e.path();
                let Ok(ft) = e.file_type() else { continue };
                let name = e.file_name().to_string_lossy().into_owned();
                if ft.is_dir() {
                    walk(&p, tag);
                } else if ft.is_file() && name.ends_with(TMP_SUFFIX) && (tag.is_empty() || name.contains(&format!(".{tag}"))) {
                    let _ = std::fs::remove_file(&p);
                }
            }
        }
        walk(&self.root, &self.tag);
    }
}

/// Writes to a temporary file in the same directory, flushes it to disk and renames it over
/// `path`. Readers see the old file or the new one, never a partial one.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), Error> {
    write_tagged(path, bytes, "")
}

/// [`write_atomic`] of what `produce` writes as it is produced (nothing is held but a small
/// buffer); returns `produce`'s result and the file's digest.
pub fn write_atomic_streamed<T>(path: &Path, produce: impl FnOnce(&mut dyn Write) -> std::io::Result<T>) -> Result<(T, Digest), Error> {
    write_tagged_with(path, "", produce)
}

/// [`write_atomic`] with the writer's tag in the temporary's name.
fn write_tagged(path: &Path, bytes: &[u8], tag: &str) -> Result<(), Error> {
    write_tagged_with(path, tag, |w| w.write_all(bytes)).map(|_| ())
}

/// A writer that hashes what passes through it.
struct Hashing<W> {
    inner: W,
    hasher: Hasher,
}

impl<W: Write> Write for Hashing<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.hasher.update(&buf[..n]);
        Ok(n)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

/// [`write_tagged`] of what `produce` writes, hashed on the way.
fn write_tagged_with<T>(path: &Path, tag: &str, produce: impl FnOnce(&mut dyn Write) -> std::io::Result<T>) -> Result<(T, Digest), Error> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    // A fresh name that nothing occupies: `create_new` refuses a planted symlink, and a name a
    // killed process with the same PID left behind (PID 1 in every container) is skipped.
    let mut tries = 0;
    let (tmp, file) = loop {
        let tmp = dir.join(format!(".{name}.{tag}{}.{}{TMP_SUFFIX}", std::process::id(), COUNTER.fetch_add(1, Ordering::Relaxed)));
        match crate::files::create_new(&tmp) {
            Ok(f) => break (tmp, f),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && tries < 1000 => tries += 1,
            Err(e) => return Err(Error::io(path, "write", e)),
        }
    };
    let result = (|| -> std::io::Result<(T, Digest)> {
        let mut w = Hashing { inner: std::io::BufWriter::with_capacity(1 << 16, file), hasher: Hasher::new() };
        let value = produce(&mut w)?;
        w.flush()?;
        let digest = w.hasher.finish();
        let f = w.inner.into_inner().map_err(|e| e.into_error())?;
        f.sync_all()?;
        drop(f);
        std::fs::rename(&tmp, path)?;
        if let Ok(d) = File::open(dir) {
            let _ = d.sync_all();
        }
        Ok((value, digest))
    })();
    result.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(path, "write", e)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("texsyn-outdir-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    #[test]
    fn second_open_is_refused_while_the_first_holds_the_lock() {
        let d = tmp("lock");
        let first = OutDir::open(&d).unwrap();
        let err = OutDir::open(&d).err().expect("second open must fail");
        assert!(err.to_string().contains("another texsyn run"), "{err}");
        assert!(matches!(err, Error::Locked { holder: Some(_), .. }), "{err:?}");
        drop(first);
        assert!(OutDir::open(&d).is_ok());
    }

    #[test]
    fn writes_are_atomic_and_temporaries_are_cleaned() {
        let d = tmp("atomic");
        let out = OutDir::open(&d).unwrap();
        out.write("a/b.png", b"12345").unwrap();
        assert_eq!(std::fs::read(d.join("a/b.png")).unwrap(), b"12345");
        std::fs::write(d.join("a/.b.png.1.2.texsyn-tmp"), b"partial").unwrap();
        drop(out);
        let _again = OutDir::open(&d).unwrap();
        assert!(!d.join("a/.b.png.1.2.texsyn-tmp").exists());
    }

    #[test]
    fn a_shard_locks_and_cleans_only_its_own_part() {
        let d = tmp("shards");
        let a = OutDir::open_part(&d, Some("shard-0-of-2")).unwrap();
        let b = OutDir::open_part(&d, Some("shard-1-of-2")).unwrap();
        assert!(OutDir::open_part(&d, Some("shard-0-of-2")).is_err(), "the same shard twice");
        drop(a);
        std::fs::write(d.join(".x.png.shard-0-of-2.7.0.texsyn-tmp"), b"mine").unwrap();
        std::fs::write(d.join(".y.png.shard-1-of-2.7.0.texsyn-tmp"), b"in flight elsewhere").unwrap();
        let _a = OutDir::open_part(&d, Some("shard-0-of-2")).unwrap();
        assert!(!d.join(".x.png.shard-0-of-2.7.0.texsyn-tmp").exists());
        assert!(d.join(".y.png.shard-1-of-2.7.0.texsyn-tmp").exists());
        drop(b);
    }

    #[test]
    fn symlinks_cannot_redirect_writes_outside() {
        let d = tmp("symlink");
        let outside = tmp("symlink-target");
        std::fs::create_dir_all(&outside).unwrap();
        let out = OutDir::open(&d).unwrap();
        std::os::unix::fs::symlink(&outside, d.join("escape")).unwrap();
        let err = out.write("escape/x.png", b"x").unwrap_err();
        assert!(err.to_string().contains("outside the output directory"), "{err}");
        assert!(!outside.join("x.png").exists());
    }
}
