//! The start-up: the parameters from the store, or the defaults, and the configuration they
//! build; the store as the main loop reads it, and what the platform does after an answer.

use super::params::{Board, Params};
use super::protocol::{Invalid, LoadError, Source, StoreError};
use super::store::Store;
use super::Install;

/// Reads the stored parameters (the main loop's view of the store).
pub trait Storage {
    /// The stored set, decoded.
    ///
    /// # Errors
    /// Why there is none to use.
    fn load(&mut self) -> Result<Params, LoadError<'static>>;
}

impl<F: embedded_storage::nor_flash::NorFlash> Storage for Store<F> {
    fn load(&mut self) -> Result<Params, LoadError<'static>> {
        Store::load(self)
    }
}

/// What the platform does after the dispatcher has answered (the answer is in the
/// transmit buffer: send it first).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Action {
    /// Store these parameters, with the control stopped, and start again
    /// ([`boot`] with the set to save).
    Save(Params),
    /// Start again.
    Restart,
}

/// How the parameters in use were found at start, and the configuration they build.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Boot {
    /// The parameters in use.
    pub params: Params,
    /// Where they came from.
    pub source: Source<'static>,
    /// The outcome of the save this start made, if one was requested.
    pub saved: Option<Result<(), StoreError>>,
    /// The configuration they build.
    pub install: Install,
}

/// Starts the application's parameters: stores `save` first when a save was requested
/// before this start, then loads the stored set; a set that is missing, of another
/// format, damaged or invalid on this board gives way to `defaults`, and the source
/// says why.
///
/// # Errors
/// The defaults themselves do not build (a firmware built for an actuator it refuses).
#[inline(never)]
pub fn boot<F: embedded_storage::nor_flash::NorFlash>(
    store: &mut Store<F>,
    defaults: &Params,
    board: &Board,
    save: Option<&Params>,
) -> Result<Boot, crate::control::config::Error> {
    let saved = save.map(|p| store.save(p));
    let stored = store.load().and_then(|p| match p.build(board) {
        Ok(install) => Ok((p, install)),
        Err(e) => Err(LoadError::Invalid(Invalid::from(e))),
    });
    match stored {
        Ok((params, install)) => Ok(Boot {
            params,
            source: Source::Stored,
            saved,
            install,
        }),
        Err(why) => Ok(Boot {
            params: *defaults,
            source: match why {
                LoadError::Empty => Source::Defaults,
                other => Source::Fallback(other),
            },
            saved,
            install: defaults.build(board)?,
        }),
    }
}
