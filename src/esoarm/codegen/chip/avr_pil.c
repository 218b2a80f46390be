/* Processor-in-the-loop shell for the ATmega328P (simavr): the generated step
 * between two writes to GPIOR0, which the harness times with avr->cycle.
 *
 *   GPIOR0 = 1   ready: the harness reads pil_out (the previous step) and writes pil_y
 *   GPIOR0 = 2   the step starts
 *   GPIOR0 = 3   the step has ended
 */
#include <avr/io.h>
#include "esoarm_controller.h"

volatile esoarm_real pil_y;
volatile esoarm_real pil_out[4];
static esoarm_state S;

int main(void)
{
    esoarm_init(&S);
    for (;;) {
        esoarm_real y;
        GPIOR0 = 1;
        y = pil_y;
        GPIOR0 = 2;
        esoarm_step(&S, y);
        GPIOR0 = 3;
        pil_out[0] = S.u;
        pil_out[1] = S.drive;
        pil_out[2] = S.duty;
        pil_out[3] = S.zhat[1];
    }
}
