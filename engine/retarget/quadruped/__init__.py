"""Quadruped retargeting (STMR): UVM, SMR (spatial), TMR (temporal)."""
