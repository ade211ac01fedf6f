"""The DeltaV PID block (spec vendor-blocks section 4): being written; registers no kind yet."""
