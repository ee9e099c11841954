//! Standard output that never panics. `println!` panics when stdout is closed (`cloth scenes |
//! head -3`); [`outln!`] and [`out!`] write through [`write()`] instead. A closed pipe is not an
//! error: further output is dropped and the command goes on (a `cloth sim` still writes its
//! frames and report). Any other write error is kept and reported by [`status()`] at exit.

use std::fmt;
use std::io::{self, Write};
use std::sync::Mutex;

/// The first write error other than a closed pipe, and whether stdout is closed.
static STATE: Mutex<(bool, Option<String>)> = Mutex::new((false, None));

/// Writes `args` to stdout, unless an earlier write found it closed.
pub fn write(args: fmt::Arguments<'_>) {
    let mut state = STATE
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    if state.0 {
        return;
    }
    let mut stdout = io::stdout().lock();
    if let Err(e) = stdout.write_fmt(args).and_then(|()| stdout.flush()) {
        state.0 = true;
        if e.kind() != io::ErrorKind::BrokenPipe {
            state.1.get_or_insert_with(|| e.to_string());
        }
    }
}

/// The error to report at exit, if a write to stdout failed other than by a closed pipe.
pub fn status() -> Option<String> {
    STATE
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .1
        .clone()
}

/// `print!` through [`write()`].
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::out::write(format_args!($($arg)*))
    };
}

/// `println!` through [`write()`].
macro_rules! outln {
    () => {
        $crate::out::write(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::out::write(format_args!("{}\n", format_args!($($arg)*)))
    };
}

pub(crate) use {out, outln};
