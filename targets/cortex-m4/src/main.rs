#![no_std]
#![no_main]

use cortex_m as _;
use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};
use panic_semihosting as _;

#[entry]
fn main() -> ! {
    hprintln!("nerflex firmware: hello from a Cortex-M4F");
    debug::exit(debug::EXIT_SUCCESS);
    loop {}
}
