"""The methods run beside `csympnet fit` on each case."""
