/* The return codes of FMI calls, numbered as both FMI versions number theirs (fmi2Status, fmi3Status): what the
 * FMUs' core returns, and what the harness's C loops read from any FMU (harness/fmi/native/fmi_calls.h). The
 * harness's Python (harness/fmi/fmu_instance.py) and the page's script (web/fmu.mjs) name them once each;
 * tests/framework/test_status_codes.py checks that the three agree with each other and with the FMI headers. */
#ifndef FMI_STATUS_H
#define FMI_STATUS_H

typedef enum { STATUS_OK = 0, STATUS_WARNING = 1, STATUS_DISCARD = 2, STATUS_ERROR = 3 } Status;

#endif
