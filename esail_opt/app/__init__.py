"""The application: solutions and their files, plots, searches, sweeps, the paper
reproduction and the command line."""
