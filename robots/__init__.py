"""The robot descriptions shipped with fusionkit, one folder per plugin family (installed as the data package
`fusionkit_robots`; each family registers its folder's files by name: `description: arascam`)."""
