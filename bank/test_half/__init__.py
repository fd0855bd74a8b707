"""The bank's TEST HALF: truths of a geared servo pendulum written from literature, without
reading the discrepancy library, to be run once after the method's rules freeze
(bank/README.md)."""
