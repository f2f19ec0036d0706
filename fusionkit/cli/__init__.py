"""The `fusionkit` command."""
