//! Shared test helpers: mocks that always check `.done()`, and an SPI
//! wrapper that injects a bus error (the SPI mock cannot).
#![allow(dead_code)]

use embedded_hal::spi::ErrorKind;
use embedded_hal_async::spi::{ErrorType, Operation, SpiDevice};
use embedded_hal_mock::eh1::delay::{CheckedDelay, Transaction as DelayTransaction};
use embedded_hal_mock::eh1::i2c::{Mock as I2cMock, Transaction as I2cTransaction};
use embedded_hal_mock::eh1::spi::{Mock as SpiMock, Transaction as SpiTransaction};

pub use embassy_futures::block_on;

/// A mock plus a clone kept aside; dropping it calls `.done()`, so every
/// test fails on a missing expectation (unless it already failed).
pub struct Checked<M: Done> {
    kept: M,
}

/// The mocks' `done`.
pub trait Done {
    fn done(&mut self);
}

impl Done for SpiMock<u8> {
    fn done(&mut self) {
        SpiMock::done(self)
    }
}

impl Done for I2cMock {
    fn done(&mut self) {
        I2cMock::done(self)
    }
}

impl Done for CheckedDelay {
    fn done(&mut self) {
        CheckedDelay::done(self)
    }
}

impl<M: Done> Drop for Checked<M> {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            self.kept.done();
        }
    }
}

pub fn spi(expect: &[SpiTransaction<u8>]) -> (SpiMock<u8>, Checked<SpiMock<u8>>) {
    let mock = SpiMock::new(expect);
    (mock.clone(), Checked { kept: mock })
}

pub fn i2c(expect: &[I2cTransaction]) -> (I2cMock, Checked<I2cMock>) {
    let mock = I2cMock::new(expect);
    (mock.clone(), Checked { kept: mock })
}

pub fn delay(expect: &[DelayTransaction]) -> (CheckedDelay, Checked<CheckedDelay>) {
    let mock = CheckedDelay::new(expect);
    (mock.clone(), Checked { kept: mock })
}

/// An SPI device that fails transaction number `fail_at` (0-based) with
/// `ErrorKind::Other` and passes every other one to the mock.
pub struct FailingSpi {
    pub inner: SpiMock<u8>,
    pub fail_at: usize,
    pub seen: usize,
}

impl ErrorType for FailingSpi {
    type Error = ErrorKind;
}

impl SpiDevice for FailingSpi {
    async fn transaction(&mut self, ops: &mut [Operation<'_, u8>]) -> Result<(), ErrorKind> {
        let n = self.seen;
        self.seen += 1;
        if n == self.fail_at {
            Err(ErrorKind::Other)
        } else {
            self.inner.transaction(ops).await
        }
    }
}
