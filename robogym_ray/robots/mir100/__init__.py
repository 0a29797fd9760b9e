"""The MiR100 mobile base: model, drive, lasers, scenes, config, state layout and card."""
