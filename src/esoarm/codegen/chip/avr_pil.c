/* Processor-in-the-loop shell for the ATmega328P (simavr): the generated step
 * between two writes to GPIOR0, which the harness times with avr->cycle.
 *
 *   GPIOR0 = 1   ready: the harness reads pil_out (the previous step) and writes pil_in
 *                (y [rad], theta_d [rad], omega_d [rad/s], accel_d [rad/s^2])
 *   GPIOR0 = 2   the step starts
 *   GPIOR0 = 3   the step has ended
 */
#include <avr/io.h>
#include "esoarm_controller.h"

volatile esoarm_real pil_in[4];
volatile esoarm_real pil_out[4];
static esoarm_state S;

int main(void)
{
    esoarm_init(&S);
    for (;;) {
        esoarm_real y, r0, r1, r2;
        GPIOR0 = 1;
        y = pil_in[0]; r0 = pil_in[1]; r1 = pil_in[2]; r2 = pil_in[3];
        GPIOR0 = 2;
        esoarm_step(&S, y, r0, r1, r2);
        GPIOR0 = 3;
        pil_out[0] = S.u;
        pil_out[1] = S.drive;
        pil_out[2] = S.duty;
        pil_out[3] = S.zhat[1];
    }
}
