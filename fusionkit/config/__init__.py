"""Run-config loading and validation (`fusionkit.config.loader.load_config`)."""
