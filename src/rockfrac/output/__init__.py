"""Writers: history and point CSV files, logs, figures."""
