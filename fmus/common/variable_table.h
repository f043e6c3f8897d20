/*
 * Types of the variable table that the builder generates into variables.h. The shared FMI layer
 * reads it to check value references, types, ranges and when a variable may be set.
 */
#ifndef EXCOSIM_VARIABLE_TABLE_H
#define EXCOSIM_VARIABLE_TABLE_H

#include <math.h> /* HUGE_VAL: the bound of a variable the table gives no min or max */

typedef enum { VT_REAL, VT_INTEGER, VT_BOOLEAN } excosim_type;

typedef enum {
    CA_PARAMETER, CA_CALCULATED_PARAMETER, CA_INPUT, CA_OUTPUT, CA_LOCAL
} excosim_causality;

typedef enum {
    VA_CONSTANT, VA_FIXED, VA_TUNABLE, VA_DISCRETE, VA_CONTINUOUS
} excosim_variability;

/* Bits of excosim_variable.set_phases: when fmi2Set* may write the variable. */
#define SET_INSTANTIATED 1 /* after fmi2Instantiate, before fmi2EnterInitializationMode */
#define SET_INIT 2         /* in initialization mode */
#define SET_STEP 4         /* between steps (inputs and tunable parameters) */

typedef struct {
    const char *name;
    excosim_type type;
    excosim_causality causality;
    excosim_variability variability;
    int set_phases;
    double start; /* 0 where the table gives no start */
    double min, max; /* the table's min and max; -HUGE_VAL and HUGE_VAL where it gives none */
} excosim_variable;

#endif
