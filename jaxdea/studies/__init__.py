"""Many solves for one question: sweeps, design, inverse characterisation (fit) and the
peak table it reads. Imports solve and below."""
