"""The flexible-link discretizations of the seeds compared on the same arms
(``flex-twin compare``): thesis Tables I-III, VI, Remark 8, frequency responses, seed 000
Tables 2 and 4, and the cost of one evaluation of the equations of motion."""
