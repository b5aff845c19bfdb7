//! The motherboard images of the examples, shared by the boards: each bin (`src/bin/mb-*.rs`)
//! names its board module as `board`, includes this file as
//! `#[path = "../mb_image.rs"] #[macro_use] mod image;` and calls [`mb_image!`] with the
//! example's tasks. `main` starts the X10 motherboard runtime and spawns one embassy task per
//! robot function. The panic and HardFault handlers and the watchdog come with x10-boards
//! (`x10_boards::watchdog`); your own robot's image looks the same (`cargo x10 new`,
//! `docs/your-first-robot.md`).

/// `mb_image!("what it runs", task_name = path::to::async_fn, ...)`: the image's `main` and
/// one embassy task per robot function, each logging the error that ends it.
macro_rules! mb_image {
    ($about:literal, $( $task:ident = $run:path ),+ $(,)?) => {
        use defmt::{info, unwrap, warn};
        use embassy_executor::Spawner;
        use x10::{MbConfig, X10};
        use x10_boards::start::MB_ADDRESS;
        // The panic handler comes with x10-boards (`x10_boards::watchdog`): safe outputs first.
        use defmt_rtt as _;

        use crate::board::{init, start_motherboard};

        #[embassy_executor::main]
        async fn main(spawner: Spawner) {
            let p = init();
            let x10 = unwrap!(start_motherboard(spawner, p, MbConfig::new(MB_ADDRESS)));
            info!("robot program: {=str}", $about);
            $( spawner.spawn(unwrap!($task(x10))); )+
        }

        $(
            #[embassy_executor::task]
            async fn $task(x10: X10) {
                if let Err(e) = $run(x10).await {
                    warn!("{=str} ended: {}", stringify!($task), e);
                }
            }
        )+
    };
}
