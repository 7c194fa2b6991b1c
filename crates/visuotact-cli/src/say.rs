//! Lines for the user that never end a run. `eprintln!` and `println!` panic (exit 101) when
//! their stream cannot be written — stderr on a full disk, stdout into a closed pipe — and a
//! panic half-way through a command can lose what it was about to save. [`note!`] writes to
//! stderr and drops a line it cannot write; [`say!`] and [`say_part!`] write to stdout and
//! keep the first failure, which [`stdout_failure`] reports when the command ends (exit 1 with
//! the reason), so output that did not arrive is never a silent success.

use std::fmt;
use std::io::Write as _;
use std::sync::Mutex;

/// The first error writing standard output.
static STDOUT_FAILURE: Mutex<Option<std::io::Error>> = Mutex::new(None);

/// A line to stderr, dropped if stderr cannot take it.
macro_rules! note {
    ($($arg:tt)*) => {
        visuotact_io::stderr_line(format_args!($($arg)*))
    };
}

/// A line to stdout; a failed write is kept for [`stdout_failure`].
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::say::to_stdout(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// Text to stdout without a newline; a failed write is kept for [`stdout_failure`].
macro_rules! say_part {
    ($($arg:tt)*) => {
        $crate::say::to_stdout(format_args!($($arg)*))
    };
}

/// Writes `args` to stdout, keeping the first error.
pub(crate) fn to_stdout(args: fmt::Arguments<'_>) {
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_fmt(args).and_then(|()| out.flush()) {
        if let Ok(mut first) = STDOUT_FAILURE.lock() {
            first.get_or_insert(e);
        }
    }
}

/// The first write to stdout that failed, if any (a closed pipe — `visuotact … | head` —
/// is not a failure: the reader had what it wanted).
pub(crate) fn stdout_failure() -> Option<std::io::Error> {
    let e = STDOUT_FAILURE.lock().ok()?.take()?;
    (e.kind() != std::io::ErrorKind::BrokenPipe).then_some(e)
}
