"""The accurate realisation, exact in time: Richardson-extrapolated modes integrated exactly over a sample, and the
compiled modal recursion that runs it."""
